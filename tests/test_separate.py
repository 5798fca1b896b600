"""The trials a diagnosis proposes to tell two readings of a log apart (twin/diagnose/separate.py)."""
from types import SimpleNamespace

import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin.diagnose.report import TRIAL_WORDS, answer
from twin.diagnose.separate import comparable, separations, settling
from twin.effects import apply_effects, candidates
from twin.errors import TwinError
from twin.synth.dataset import generate
from twin.synth.manoeuvres import TRIALS, trial, trial_program

YARDSTICK = {"u": 0.05, "v": 0.03, "r": 0.01}  # m/s, m/s, rad/s: a twin's misfit on a log


@pytest.fixture(scope="module")
def blueboat():
    return vessel_mod.load("blueboat")


def test_one_twin_read_twice_is_separated_by_no_trial(blueboat):
    """Identical readings must differ by nothing on any trial: a difference here would be the engine's
    own, and every proposal would rest on it."""
    seps = separations(blueboat, blueboat, YARDSTICK)
    assert [s.trial for s in sorted(seps, key=lambda s: s.trial)] == sorted(TRIALS)
    assert all(s.difference == 0.0 and s.share == 0.0 and s.minutes is None for s in seps)


def test_a_weaker_thrust_and_a_loss_with_speed_part_on_spins(blueboat):
    """Under way the two take the same thrust off; on the spot the loss with speed takes almost none
    (only the thrusters' own speed r·y) while a weaker thrust takes 15 %: spins tell them apart in r,
    and still do with the loss's own coefficient refitted to the spins."""
    weaker = apply_effects(blueboat, [("thrust_gain", {"scale": 0.85})])
    losing = apply_effects(blueboat, [("thrust_speed_loss", {"advance_loss": 3.0})])
    seps = separations(weaker, losing, YARDSTICK)
    best = seps[0]
    assert (best.trial, best.dof) == ("spins", "r")
    assert best.ratio > 5.0 and best.share == 1.0
    assert best.minutes == pytest.approx(10 * 3 * 10.0 / 60.0)  # ten blocks of three 10-s windows
    assert [s.ratio for s in seps] == sorted((s.ratio for s in seps), reverse=True)
    refit = separations(weaker, losing, YARDSTICK, rival=candidates(blueboat, ["log"])["thrust_speed_loss"])
    assert refit[0].refitted and refit[0].trial == "spins" and refit[0].ratio > 2.0


def test_a_drag_and_a_thrust_loss_part_where_no_thrust_acts(blueboat):
    """More surge drag and a weaker thrust come to nearly one top speed; accelerating and coasting down
    they part: full ahead and coast must move u by more than a twin's misfit in a good share of its
    windows (the steady part's windows agree)."""
    draggy = apply_effects(blueboat, [("surge_resistance", {"Xu": 1.0, "Xuu": 1.4})])
    weaker = apply_effects(blueboat, [("thrust_gain", {"scale": 0.85})])
    coast = next(s for s in separations(draggy, weaker, YARDSTICK) if s.trial == "full_ahead_coast")
    assert coast.dof == "u" and 0.3 < coast.share < 1.0 and coast.difference > 0.02


def test_a_ship_gets_no_pwm_trial():
    ship = vessel_mod.load("esso_osaka")
    assert separations(ship, ship, YARDSTICK) == []


def test_trials_start_at_rest_and_a_dataset_repeats_them(blueboat):
    for name in TRIALS:
        mean, diff = trial_program(name)
        assert mean[0] == 0.0 and diff[0] == 0.0, name
        assert np.all(np.abs(trial(name).values - 1500.0) <= 400.0)
    with pytest.raises(TwinError, match="unknown trial"):
        trial_program("barrel_roll")
    ds = generate(blueboat, n_segments=1, manoeuvres=["spins"], seed=1, segment_s=(80.0, 80.0))
    pwm = ds.runs[0].pwm_us
    # two programs of 39 s: both hands of spin, each twice
    spins_right = np.sum((pwm[1:, 0] > 1600) & (pwm[:-1, 0] <= 1600))
    spins_left = np.sum((pwm[1:, 1] > 1600) & (pwm[:-1, 1] <= 1600))
    assert spins_right == 2 and spins_left == 2


def test_the_answer_says_which_trial_settles_an_unsettled_rival():
    sep = {"trial": "spins", "dof": "r", "difference": 0.2, "ratio": 17.0, "share": 1.0, "minutes": 5.0}
    rival = {"name": "thrust_speed_loss", "z": 2.9, "separable": False, "held_out_gain": 0.2, "parameters": {}}
    kept = {"name": "thrust_gain", "parameters": {"scale": 0.85}, "ci": {}, "z": 3.5, "excess_gain": 0.8,
            "evidence": {"blocks_for": 12, "blocks_against": 0}, "rivals": [rival],
            "separations": {"thrust_speed_loss": [sep]}}
    fit = {k: {"r2": 0.5} for k in "uvr"}
    d = SimpleNamespace(effects=[kept], rounds=[], unexplained=[], located=[], fit_before=fit, fit_after=fit,
                        prior=vessel_mod.load("blueboat"), windows={"length_s": 10.0, "windows": 36})
    first = answer(d)["next"][0]
    assert first.startswith("to tell thrust_gain from thrust_speed_loss: " + TRIAL_WORDS["spins"])
    assert "about 5 min of it" in first and "11 °/s in r" in first and "17.0×" in first


def test_a_rival_refitted_on_a_trial_keeps_only_what_it_cannot_take_up(blueboat):
    """As fitted on a log, a weaker thrust and more yaw damping part widely in spins; recorded, the spins
    would move the damping's own yaw scale, so the trial is judged with the rival refitted to it: what
    is left must be far smaller than the unrefitted difference, and no refit may widen a separation."""
    weaker = apply_effects(blueboat, [("thrust_gain", {"scale": 0.85})])
    damped = apply_effects(blueboat, [("quadratic_damping", {"Nrr": 1.6})])
    plain = {s.trial: s for s in separations(weaker, damped, YARDSTICK)}
    refit = {s.trial: s for s in separations(weaker, damped, YARDSTICK,
                                             rival=candidates(blueboat, ["log"])["quadratic_damping"])}
    assert plain["spins"].ratio > 5.0
    assert refit["spins"].refitted and refit["spins"].ratio < 0.5 * plain["spins"].ratio
    assert all(refit[t].ratio <= plain[t].ratio * (1 + 1e-6) for t in refit if refit[t].refitted)


def test_no_trial_is_proposed_that_parts_the_readings_by_less_than_the_twin_misses():
    """Two readings that share their quantity (surge_resistance's Xuu is quadratic_damping's) part on no
    trial once refitted: proposing the best of them anyway sent a user to record minutes that settle
    nothing. The answer must say no trial parts them."""
    weak = [{"trial": "full_ahead_coast", "dof": "u", "difference": 0.004, "ratio": 0.1, "share": 0.0,
             "minutes": None, "refitted": True},
            {"trial": "spins", "dof": "r", "difference": 0.2, "ratio": 9.0, "share": 1.0, "minutes": 5.0,
             "refitted": False}]
    assert settling(weak) is None  # the unrefitted 9× is an upper bound the refit did not confirm
    good = [{**weak[0], "ratio": 2.5, "share": 0.8, "minutes": 6.25}] + weak[1:]
    assert settling(good)["trial"] == "full_ahead_coast"
    rival = {"name": "quadratic_damping", "z": 1.0, "separable": False, "held_out_gain": 0.2, "parameters": {}}
    kept = {"name": "surge_resistance", "parameters": {"Xuu": 1.5}, "ci": {}, "z": 3.5, "excess_gain": 0.8,
            "evidence": {"blocks_for": 12, "blocks_against": 0}, "rivals": [rival],
            "separations": {"quadratic_damping": weak}}
    fit = {k: {"r2": 0.5} for k in "uvr"}
    d = SimpleNamespace(effects=[kept], rounds=[], unexplained=[], located=[], fit_before=fit, fit_after=fit,
                        prior=vessel_mod.load("blueboat"), windows={"length_s": 10.0, "windows": 36})
    first = answer(d)["next"][0]
    assert first.startswith("to tell surge_resistance from quadratic_damping: none of the trials tried")
    assert "at best 0.1×" in first


def test_a_window_restarted_from_the_first_reading_is_its_own_run_for_the_same_twin(blueboat):
    """A window of the second reading starts from the first's position and velocities with its own lag
    state and its commands carried from the trial's start (a delay reaches back before the window): for
    the same twin with a lag and a delay every window must be the continuous run, or a lag or delay
    alone would read as a separation (a lag reset to zero at each start dipped r by 0.14 rad/s)."""
    lagged = apply_effects(blueboat, [("thruster_lag", {"lag_s": 0.4}), ("input_delay", {"delay_s": 0.6})])
    seps = separations(lagged, lagged, YARDSTICK)
    assert len(seps) == len(TRIALS)
    assert all(s.difference < 1e-9 and s.minutes is None for s in seps)


def test_only_effects_a_trial_runs_are_compared():
    """A sensor's effect does not change the velocities a trial runs, and a per-log one has no log there:
    their rivals must get no trial (an answer that no trial parts them would be wrong)."""
    assert comparable("thrust_gain") and comparable("quadratic_damping") and comparable("thruster_lag")
    assert not comparable("heading_bias") and not comparable("gnss_latency") and not comparable("current")
    assert not comparable("wind_per_log") and not comparable("heading_bias_per_log")
