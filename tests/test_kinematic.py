"""Sensor and timing effects told from a log's kinematics alone (twin.fit.kinematic), on logs made
here from a known truth: a hull spinning both ways with its antenna off the twin's site, and a hull
answering input steps with the input log or the heading late."""
import math
from dataclasses import replace

import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin.fit.kinematic import input_answers, input_timing, kinematic_findings, lever_arm, with_findings
from twin.geodesy import geodetic_from_ned
from twin.recording import Recording, Stream

NEUTRAL = 1511.0


def _gnss(t, north, east, rng, every=2):
    """A 5-Hz receiver logged at 10 Hz (each fix repeated once), 2 cm of noise."""
    n = north + rng.normal(0, 0.02, len(t))
    e = east + rng.normal(0, 0.02, len(t))
    held = (np.arange(len(t)) // every) * every
    lat, lon = geodetic_from_ned(n[held], e[held], 63.4, 10.3)[:2]
    return Stream(t.copy(), {"lat_deg": lat, "lon_deg": lon})


def _spins(antenna_xy, creep_m_s=0.0, seed=0, sideslip_m=0.0) -> Recording:
    """Spins on the spot both ways (0.6 rad/s for 3-5 s) between slow drifts; the hull creeps ahead at
    `creep_m_s` while it spins (a weaker reverse thrust) and sideslips by `sideslip_m` per unit of its
    rate (the sway a creep carries: its middle turns about a point that far ahead), its reference point
    wanders smoothly."""
    rng = np.random.default_rng(seed)
    dt = 0.1
    t = np.arange(0.0, 240.0, dt)
    r = np.zeros(len(t))
    k = 50
    while k < len(t) - 80:
        length = int(rng.uniform(30, 50))
        r[k:k + length] = rng.choice([-1.0, 1.0]) * 0.6
        k += length + int(rng.uniform(40, 90))
    r = np.convolve(r, np.ones(5) / 5, mode="same")  # a hull takes half a second to spin up
    psi = np.cumsum(r) * dt
    creep = creep_m_s * (np.abs(r) > 0.3)
    drift_n = 0.03 * t + 0.4 * np.sin(t / 37.0)
    drift_e = -0.02 * t + 0.3 * np.cos(t / 29.0)
    sway = -sideslip_m * r * (np.abs(r) > 0.3)
    north = drift_n + np.cumsum(creep * np.cos(psi) - sway * np.sin(psi)) * dt
    east = drift_e + np.cumsum(creep * np.sin(psi) + sway * np.cos(psi)) * dt
    x, y = antenna_xy
    north_a = north + np.cos(psi) * x - np.sin(psi) * y
    east_a = east + np.sin(psi) * x + np.cos(psi) * y
    heading = Stream(t.copy(), {"psi_rad": np.mod(psi + np.radians(0.3) * rng.standard_normal(len(t)), 2 * np.pi)})
    pwm = Stream(t.copy(), {"left_us": np.full(len(t), NEUTRAL), "right_us": np.full(len(t), NEUTRAL)})
    rec = Recording("spins.csv", "csv", gnss=_gnss(t, north_a, east_a, rng), heading=heading, pwm=pwm)
    rec.pwm_neutral_us = (NEUTRAL, NEUTRAL)
    return rec


@pytest.fixture(scope="module")
def blueboat():
    return vessel_mod.load("blueboat")


@pytest.mark.parametrize("antenna", [(0.3, 0.0), (-0.2, 0.3), (0.15, -0.25)])
def test_an_antenna_off_the_twins_site_is_found_from_spins_both_ways(blueboat, antenna):
    got = lever_arm([_spins(antenna, seed=1)], blueboat)
    assert got.told and got.effect == "gnss_lever_arm"
    assert got.values["dx_m"] == pytest.approx(antenna[0], abs=0.05)
    assert got.values["dy_m"] == pytest.approx(antenna[1], abs=0.05)


def test_an_antenna_where_the_twin_has_it_is_not_named_and_the_creep_is_not_taken_for_one(blueboat):
    got = lever_arm([_spins((0.0, 0.0), seed=2)], blueboat)
    assert not got.told and got.absent
    assert abs(got.change["dx_m"]) < 0.05 and abs(got.change["dy_m"]) < 0.05


def test_a_hull_that_creeps_while_it_spins_has_no_antenna_named(blueboat):
    """A creep carries a sideslip that moves the point the hull turns about, as an antenna fore or aft
    would: the kinematics cannot tell them apart, so neither is named, and neither is ruled out."""
    got = lever_arm([_spins((0.0, 0.0), creep_m_s=0.12, sideslip_m=0.25, seed=2)], blueboat)
    assert not got.told and not got.absent and "creeps" in got.why
    assert got.detail["creep_m_s_per_rad_s"] == pytest.approx(-0.12 / 0.6, abs=0.05)


def test_an_antenna_the_twin_already_carries_is_read_against_it(blueboat):
    from twin.effects import apply_effects

    moved = apply_effects(blueboat, ["gnss_lever_arm=0.3,0"])
    got = lever_arm([_spins((0.3, 0.0), seed=3)], moved)
    assert not got.told and abs(got.change["dx_m"]) < 0.05


def test_a_track_given_as_the_body_origins_is_read_for_its_offset_and_a_twin_run_is_left_out():
    """The Yellowfish's antenna site is 0.38 m off its origin. A measured track the log gives as the
    origin's (a model ship's pond tracking) tells the sensors' offset from the origin, not from the
    site: a point tracked 0.3 m ahead is found 0.3 m ahead, alone or beside a receiver's log whose
    antenna sits 0.3 m ahead of the site. A twin run's exact track has no antenna and is left out
    (guards against reading it as 0.32 m off the site)."""
    from twin.recording import EXACT_ORIGIN, TRACKED_ORIGIN

    yellowfish = vessel_mod.load("yellowfish")
    tracked = _spins((0.3, 0.0), seed=1)
    tracked.meta["positions"] = TRACKED_ORIGIN
    got = lever_arm([tracked], yellowfish)
    assert got.told and got.values["dx_m"] == pytest.approx(0.3, abs=0.05) and abs(got.values["dy_m"]) < 0.05
    site = (-0.275, 0.2625)  # the Yellowfish's MJCF antenna: a receiver's log there, the point 0.3 m ahead of it
    receiver = _spins((site[0] + 0.3, site[1]), seed=4)
    got = lever_arm([tracked, receiver], yellowfish)
    assert got.told and got.values["dx_m"] == pytest.approx(0.3, abs=0.05) and abs(got.values["dy_m"]) < 0.05
    exact = _spins((0.0, 0.0), seed=1)
    exact.meta["positions"] = EXACT_ORIGIN
    got = lever_arm([exact], yellowfish)
    assert not got.told and not got.absent and got.basis.startswith("0 windows")


def _answers(vessel, clock_s=0.0, heading_late_s=0.0, seed=0, gnss_late_s=0.0) -> Recording:
    """A hull answering its thrusters as a first-order surge (τ 1 s) and yaw (τ 0.3 s) model through the
    twin's thrust map, driven by PWM held between random steps; PWM logged clock_s late, heading
    heading_late_s late, GNSS on time."""
    rng = np.random.default_rng(seed)
    dt = 0.01
    t = np.arange(0.0, 400.0, dt)
    n_steps = 70
    times = np.sort(rng.uniform(2.0, 395.0, n_steps))
    mean = rng.uniform(-50, 350, n_steps + 1)
    diff = rng.uniform(-300, 300, n_steps + 1) * (rng.uniform(size=n_steps + 1) < 0.7)
    k = np.searchsorted(times, t, side="right")
    left = np.clip(NEUTRAL + mean[k] + diff[k] / 2, 1100, 1900)
    right = np.clip(NEUTRAL + mean[k] - diff[k] / 2, 1100, 1900)
    th = vessel.thrusters
    force = th.thrust_from_pwm(np.column_stack([left, right])) * np.array([th.gain_left, th.gain_right])
    u = np.zeros(len(t))
    r = np.zeros(len(t))
    for i in range(1, len(t)):
        u[i] = u[i - 1] + dt * (0.06 * force[i - 1].sum() - u[i - 1]) / 1.0
        r[i] = r[i - 1] + dt * (0.02 * (force[i - 1, 0] - force[i - 1, 1]) - r[i - 1]) / 0.3
    psi = np.cumsum(r) * dt
    north, east = np.cumsum(u * np.cos(psi)) * dt, np.cumsum(u * np.sin(psi)) * dt
    log_t = np.arange(1.0, 399.0, 0.1)
    at = lambda x, when: np.interp(when, t, x)  # noqa: E731
    heading = Stream(log_t.copy(), {"psi_rad": np.mod(at(psi, log_t - heading_late_s)
                                                     + np.radians(0.3) * rng.standard_normal(len(log_t)), 2 * np.pi)})
    pwm_idx = np.searchsorted(t, log_t - clock_s, side="right") - 1
    pwm = Stream(log_t.copy(), {"left_us": left[pwm_idx], "right_us": right[pwm_idx]})
    rec = Recording("steps.csv", "csv", gnss=_gnss(log_t, at(north, log_t - gnss_late_s), at(east, log_t - gnss_late_s),
                                                   rng), heading=heading,
                    pwm=pwm)
    rec.pwm_neutral_us = (NEUTRAL, NEUTRAL)
    return rec


@pytest.mark.parametrize("late", [0.3, 0.5])
def test_an_input_log_late_moves_both_answers_and_is_named_a_clock_offset(blueboat, late):
    clock, heading, fixes = input_timing([_answers(blueboat, clock_s=late, seed=4)], blueboat)
    assert clock.told and clock.values["pwm_clock_offset_s"] == pytest.approx(late, abs=0.06)
    assert not heading.told and not fixes.told


@pytest.mark.parametrize("late", [0.3, 0.5])
def test_a_late_heading_moves_the_yaw_answer_alone_and_is_named(blueboat, late):
    clock, heading, fixes = input_timing([_answers(blueboat, heading_late_s=late, seed=5)], blueboat)
    assert heading.told and heading.values["heading_latency_s"] == pytest.approx(late, abs=0.08)
    assert not clock.told and not fixes.told


def test_late_gnss_fixes_move_the_surge_answer_alone_and_are_named(blueboat):
    clock, heading, fixes = input_timing([_answers(blueboat, gnss_late_s=0.4, seed=10)], blueboat)
    assert fixes.told and fixes.values["gnss_latency_s"] == pytest.approx(0.4, abs=0.08)
    assert not clock.told and not heading.told


def test_an_input_log_early_is_not_named_as_a_lag_would_look_the_same(blueboat):
    clock, _, _ = input_timing([_answers(blueboat, clock_s=-0.3, seed=4)], blueboat)
    assert not clock.told and not clock.absent
    assert clock.change["pwm_clock_offset_s"] == pytest.approx(-0.3, abs=0.06)


def test_on_time_streams_name_nothing_and_rule_the_timing_effects_out(blueboat):
    clock, heading, fixes = input_timing([_answers(blueboat, seed=6)], blueboat)
    assert not clock.told and not heading.told and not fixes.told
    assert clock.absent and heading.absent and fixes.absent and abs(clock.change["pwm_clock_offset_s"]) < 0.06


def test_a_shift_read_at_the_floor_itself_is_not_named(blueboat, monkeypatch):
    """Streams at 10 Hz: the floor is 0.15 s. A surge answering 0.15 s after the yaw, read on the
    shifts' grid, is the resolution, not a late GNSS; 0.17 s exceeds it."""
    from twin.fit import kinematic

    def answers(surge_s):
        return lambda recordings, vessel: (kinematic.Answer("surge", surge_s, 0.03, 8, 9),
                                           kinematic.Answer("yaw", 0.11, 0.04, 8, 9), False,
                                           {"input": 0.1, "heading": 0.1})
    monkeypatch.setattr(kinematic, "_answers", answers(-0.04))
    _, _, fixes = input_timing([], blueboat)
    assert not fixes.told
    monkeypatch.setattr(kinematic, "_answers", answers(-0.06))
    _, _, fixes = input_timing([], blueboat)
    assert fixes.told and fixes.change["gnss_latency_s"] == pytest.approx(0.17)


def test_an_early_heading_is_not_named(blueboat):
    """A heading filter delays: a heading that seems early is a clock's matter, not a latency."""
    _, heading, _ = input_timing([_answers(blueboat, heading_late_s=-0.4, seed=7)], blueboat)
    assert not heading.told and heading.change["heading_latency_s"] < -0.25


def test_findings_are_put_into_the_twin_as_the_library_applies_them(blueboat):
    rec = _answers(blueboat, clock_s=0.4, seed=8)
    found = kinematic_findings([rec], blueboat)
    amended = with_findings(blueboat, found)
    assert amended.sensors.pwm_clock_offset_s == pytest.approx(0.4, abs=0.06)
    # read against the amended twin, the clock has nothing left to tell
    again = input_timing([rec], amended)[0]
    assert not again.told and abs(again.change["pwm_clock_offset_s"]) < 0.06


def test_the_twins_own_runs_set_the_zero_other_runs_are_timed_against(blueboat):
    """Runs whose logs answer 0.25 s ahead of the twin's timing (a template that is not the twin's
    dynamics does that too) make the zero: another such run is on time, and a run 0.4 s later still
    is named 0.4 s late."""
    own = _answers(blueboat, clock_s=0.25, seed=11)
    surge_s, yaw_s = input_answers([own], blueboat)
    assert surge_s == pytest.approx(0.25, abs=0.05) and yaw_s == pytest.approx(0.25, abs=0.05)
    zeroed = replace(blueboat, sensors=replace(blueboat.sensors, input_answer_s=(surge_s, yaw_s)))
    clock, heading, fixes = input_timing([_answers(blueboat, clock_s=0.25, seed=12)], zeroed)
    assert not clock.told and not heading.told and not fixes.told and clock.absent
    clock, _, _ = input_timing([_answers(blueboat, clock_s=0.65, seed=13)], zeroed)
    assert clock.told and clock.change["pwm_clock_offset_s"] == pytest.approx(0.4, abs=0.06)


def test_without_spins_both_ways_the_antenna_is_not_told_and_not_ruled_out(blueboat):
    rec = _answers(blueboat, seed=9)
    got = lever_arm([rec], blueboat)
    assert not got.told and not got.absent and got.why
    assert math.isfinite(got.values["dx_m"])


def test_the_heading_timing_is_the_kinematics_alone_only_where_every_log_has_a_gyro():
    """The antenna and the GNSS fixes' latency are never searched in the dynamics; the heading's
    timing joins them where every log has a gyro to read it against, and only then."""
    from twin.diagnose.doctor import kinematic_only

    t = np.arange(0.0, 10.0, 0.1)
    gyro = Recording(source="a", kind="csv", imu=Stream(t, {"yaw_rate_rads": np.zeros_like(t)}))
    bare = Recording(source="b", kind="csv")
    assert kinematic_only([bare]) == {"gnss_lever_arm", "gnss_latency"}
    assert kinematic_only([gyro]) == {"gnss_lever_arm", "gnss_latency", "heading_latency"}
    assert kinematic_only([gyro, bare]) == {"gnss_lever_arm", "gnss_latency"}


def test_a_kinematics_only_effect_is_left_out_of_the_search_with_or_without_a_kinematic_step():
    """Without findings (the kinematic step switched off) the antenna and the GNSS latency are still
    not searched; a told or absent finding is left out too, one neither told nor absent is searched."""
    from types import SimpleNamespace

    from twin.diagnose.doctor import not_searched

    bare = Recording(source="b", kind="csv")
    assert not_searched([], [bare], []) == {"gnss_lever_arm", "gnss_latency"}
    told = SimpleNamespace(effect="clock_offset", told=True, absent=False)
    unsure = SimpleNamespace(effect="heading_latency", told=False, absent=False)
    assert not_searched([told, unsure], [bare], []) == {"gnss_lever_arm", "gnss_latency", "clock_offset"}
    measured = SimpleNamespace(sigma_deg=0.4)
    assert "heading_bias" in not_searched([], [bare], [measured])
    assert "heading_bias" not in not_searched([], [bare], [SimpleNamespace(sigma_deg=None)])
