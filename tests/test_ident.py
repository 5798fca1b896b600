"""Synthetic datasets, free-run windows on the batch engine, evaluation and the
simulation fit: each checked against a truth it did not see."""
import json
from pathlib import Path
from dataclasses import replace

import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin.engine.mjcf import compile_vessel
from twin.errors import TwinError
from twin.fit import simfit
from twin.fit.objective import Objective
from twin.synth.dataset import PROFILES, SensorNoise, generate
from twin.effects import coefficients, parse_effect
from twin.effects.coefficients import PWM_THRUSTER_TERMS
from twin.fit.evaluate import TwinPredictor, evaluate, manoeuvres, misfit_by_manoeuvre
from twin.fit.windows import ModelCache, Window, make_windows, measured, predict
from twin.physics.sensors import antenna_body_m
from twin.formats import read_recording, write_recording
from twin.fit.calibrate import prepare_for
from twin.fit.crossval import each_folds, jackknife_vessels
from twin.prepare.prepared import prepared_from_run
from twin.run import Run

QUIET = PROFILES["none"]


@pytest.fixture(scope="module")
def yellowfish_vessel():
    return vessel_mod.load("yellowfish")


def _truth_preps(ds):
    """The noise-free states of a dataset at 10 Hz as prepared recordings (exact velocities)."""
    out = []
    for r in ds.runs:
        k = slice(None, None, 5)
        out.append(prepared_from_run(Run(r.t[k], r.eta[k], r.nu[k], r.pwm_us[k], r.thrust_n[k])))
    return out


def test_dataset_is_reproducible_and_logs_what_the_sensors_see(yellowfish_vessel):
    effects = ["heading_bias=3", "clock_offset=0.2", "gnss_lever_arm=0.1,-0.05"]
    a = generate(yellowfish_vessel, effects=effects, n_segments=2, seed=4, noise=QUIET, segment_s=(20, 25))
    b = generate(yellowfish_vessel, effects=effects, n_segments=2, seed=4, noise=QUIET, segment_s=(20, 25))
    np.testing.assert_array_equal(a.recording.gnss["lat_deg"], b.recording.gnss["lat_deg"])
    run = a.runs[0]
    rec = a.recording
    # heading: the truth plus the bias, at 50 Hz
    psi_true = np.interp(rec.heading.t[:500], run.t, run.eta[:, 2])
    err = np.angle(np.exp(1j * (rec.heading["psi_rad"][:500] - psi_true)))
    np.testing.assert_allclose(np.degrees(err), 3.0, atol=1e-9)
    # PWM stamps 0.2 s late, every 100 ms
    assert rec.pwm.t[0] == pytest.approx(run.t[0] + 0.2)
    assert np.median(np.diff(rec.pwm.t)) == pytest.approx(0.1)
    # GNSS at 5 Hz at the moved antenna
    cv = compile_vessel(a.truth_vessel)
    arm = antenna_body_m(cv.geometry.gnss_pos_m, a.truth_vessel.sensors)
    np.testing.assert_allclose(arm, np.array(cv.geometry.gnss_pos_m[:2]) + [0.1, -0.05])
    assert np.median(np.diff(rec.gnss.t)) == pytest.approx(0.2)
    truth = a.truth()
    assert truth["effects"][0]["name"] == "heading_bias" and len(truth["states"]) == 2
    json.dumps(truth, allow_nan=False)


def test_heading_bias_per_log_acts_on_the_log_of_that_name_only(yellowfish_vessel):
    text = "heading_bias_per_log=synthetic:yellowfish:seed4:-2.5,other.bin:7"
    effect = parse_effect(text)
    assert effect.params == {"synthetic:yellowfish:seed4": -2.5, "other.bin": 7.0} and parse_effect(effect.text) == effect
    for bad in ("heading_bias_per_log=run.bin", "heading_bias_per_log=run.bin:200", "heading_bias_per_log=:3"):
        with pytest.raises(TwinError, match="heading_bias_per_log"):
            parse_effect(bad)
    ds = generate(yellowfish_vessel, effects=[text, "heading_bias=1"], n_segments=1, seed=4, noise=QUIET,
                  segment_s=(20, 25))
    run, rec = ds.runs[0], ds.recording
    psi_true = np.interp(rec.heading.t[:200], run.t, run.eta[:, 2])
    err = np.angle(np.exp(1j * (rec.heading["psi_rad"][:200] - psi_true)))
    np.testing.assert_allclose(np.degrees(err), 1.0 - 2.5, atol=1e-9)  # common bias plus this log's own
    assert ds.truth_vessel.sensors.for_log("/elsewhere/other.bin").heading_bias_deg == pytest.approx(8.0)


def test_dataset_round_trips_through_a_tlog(tmp_path, yellowfish_vessel):
    ds = generate(yellowfish_vessel, n_segments=2, seed=2, segment_s=(20, 25))
    write_recording(ds.recording, tmp_path / "d.tlog")
    back = read_recording(tmp_path / "d.tlog")
    assert len(back.gnss) == len(ds.recording.gnss) and len(back.pwm) == len(ds.recording.pwm)
    prep = prepare_for(back, compile_vessel(yellowfish_vessel))
    assert len(prep.segments) == 2


@pytest.mark.parametrize("change", [{"lag_s": 0.3}, {"delay_s": 0.2}, {"advance_loss": 1.0},
                                    {"decay_per_min": 0.1}, {"gain_right": 0.8}, {"ramp_s": 2.0},
                                    {"ramp_s": 1.5, "lag_s": 0.3}])
def test_windows_reproduce_the_generating_twin(yellowfish_vessel, change):
    v = replace(yellowfish_vessel, thrusters=replace(yellowfish_vessel.thrusters, **change))
    ds = generate(v, n_segments=2, seed=3, noise=QUIET, segment_s=(25, 30), manoeuvres=["rc", "circle_varying"])
    preps = _truth_preps(ds)
    wins = make_windows(preps, 5.0, 2.5)
    # a model compiled for the plain vessel, re-parameterised at run time, must give the same dynamics
    cache = ModelCache()
    cache.model(yellowfish_vessel)
    pred = predict(v, preps, wins, cache)[0]
    _, nu = measured(preps, wins)
    # a lag is filtered ahead of the engine (each step's mean thrust, lagged_thrust), where the run
    # integrates it within the step: second order in the 0.02-s step, 1e-4 rad/s at most here
    assert np.nanmax(np.abs(pred.nu - nu)) < (2e-4 if "lag_s" in change else 1e-6)


def test_a_kept_cache_predicts_to_the_bit_what_a_fresh_one_does(yellowfish_vessel):
    """The cache keeps each window's thrust commands and initial state across vessels (a Jacobian's, a
    round's candidates): a lagged twin carries its actuator states, a velocity offset its own start,
    and a prediction through a cache that has seen other vessels equals one through a fresh cache."""
    ds = generate(yellowfish_vessel, n_segments=2, seed=4, noise=QUIET, segment_s=(25, 30))
    preps = _truth_preps(ds)
    wins = make_windows(preps, 5.0, 2.5)
    lagged = replace(yellowfish_vessel, thrusters=replace(yellowfish_vessel.thrusters, lag_s=0.3))
    vessels, offsets = [yellowfish_vessel, lagged, yellowfish_vessel], [None, None, (0.05, -0.02, 0.01)]
    kept = ModelCache()
    predict([lagged, yellowfish_vessel], preps, wins, kept)  # the kept cache has seen these windows
    again = predict(vessels, preps, wins, kept, nu_offsets=offsets)
    fresh = [predict(v, preps, wins, ModelCache(), nu_offsets=[o])[0] for v, o in zip(vessels, offsets)]
    for a, b in zip(again, fresh):
        np.testing.assert_array_equal(a.nu, b.nu)
        np.testing.assert_array_equal(a.eta, b.eta)
    assert np.nanmax(np.abs(again[2].nu[:, 1:] - again[0].nu[:, 1:])) > 1e-3  # the offset's start was its own


def test_a_window_rolled_out_before_by_the_same_twin_is_not_rolled_out_again(yellowfish_vessel, monkeypatch):
    """The cache keeps each window's states by the model, the initial state and the controls: the
    same twin over the same windows runs nothing again (the same numbers), a twin one coefficient
    apart runs all its windows, and one twin asked twice in one batch runs once."""
    import twin.fit.windows as windows_mod

    ds = generate(yellowfish_vessel, n_segments=2, seed=4, noise=QUIET, segment_s=(25, 30))
    preps = _truth_preps(ds)
    wins = make_windows(preps, 5.0, 2.5)
    rolled = []
    real = windows_mod.batch.rollout

    def counted(models, states, controls, nthread=None):
        rolled.append(len(states))
        return real(models, states, controls, nthread=nthread)

    monkeypatch.setattr(windows_mod.batch, "rollout", counted)
    kept = ModelCache(keep_runs=True)
    first = predict(yellowfish_vessel, preps, wins, kept)[0]
    again = predict([yellowfish_vessel, yellowfish_vessel], preps, wins, kept)
    draggier = replace(yellowfish_vessel, damping=replace(yellowfish_vessel.damping, Xu=1.1 * yellowfish_vessel.damping.Xu - 0.1))
    other = predict([draggier, draggier], preps, wins, kept)[0]
    assert rolled == [len(wins), len(wins)]  # the first twin once; the draggier twin once for both
    plain = ModelCache()  # keeps no runs (a Monte Carlo draw's twin runs once)
    predict(yellowfish_vessel, preps, wins, plain), predict(yellowfish_vessel, preps, wins, plain)
    assert rolled == [len(wins)] * 4
    for a in again:
        np.testing.assert_array_equal(a.nu, first.nu)
    assert np.nanmax(np.abs(other.nu[:, 1:] - first.nu[:, 1:])) > 1e-4


def test_two_recordings_of_one_name_and_span_are_driven_each_by_its_own_pwm(yellowfish_vessel):
    """The cache keys a window's commands by what the recording logged, not by its name: two runs
    that share a source name, a start and a length but not their PWM are each driven by their own."""
    from twin.drive import InputSeries
    from twin.simulation import simulate_run

    t = np.arange(0.0, 20.0, 0.1)
    runs = [prepared_from_run(simulate_run(yellowfish_vessel, inputs=InputSeries(
        t, np.tile(pwm, (len(t), 1)), "pwm"), duration_s=19.9).run) for pwm in ([1800.0, 1800.0], [1800.0, 1300.0])]
    assert runs[0].settings.source == runs[1].settings.source
    both = predict(yellowfish_vessel, runs, [Window(0, 0, 150), Window(1, 0, 150)], ModelCache())[0]
    alone = predict(yellowfish_vessel, [runs[1]], [Window(0, 0, 150)], ModelCache())[0]
    np.testing.assert_array_equal(both.nu[1], alone.nu[0])
    assert abs(alone.nu[0, 150, 2]) > 0.1  # the second run turns


def test_a_lag_of_hundredths_of_a_second_is_held_at_the_candidates_coarse_step(yellowfish_vessel):
    """A thrust lag far below the candidate twins' coarse RK4 step would run away integrated by RK4
    (|hλ| 5 for 0.01 s at 0.05 s) and stop the fit at that edge: filtered ahead of the engine, it
    needs no finer step, and the generating twin reproduces its own run at 0.05 and 0.1 s."""
    from twin.fit.windows import comfortable_timestep

    quick = replace(yellowfish_vessel, thrusters=replace(yellowfish_vessel.thrusters, lag_s=0.01))
    ds = generate(quick, n_segments=1, seed=5, noise=QUIET, segment_s=(20, 20), manoeuvres=["rc"])
    preps = _truth_preps(ds)
    assert comfortable_timestep(compile_vessel(quick), preps, 1.5, 0.05) == pytest.approx(0.1)  # the grid
    wins = make_windows(preps, 10.0, 5.0)
    _, nu = measured(preps, wins)
    for step in (0.05, 0.1):
        coarse = predict(quick, preps, wins, ModelCache(step))[0]
        assert np.nanmax(np.abs(coarse.nu - nu)) < 0.02 and not coarse.diverged


def test_evaluate_tells_the_truth_from_a_wrong_twin(yellowfish_vessel):
    ds = generate(yellowfish_vessel, n_segments=3, seed=5, segment_s=(30, 40))
    preps = [prepare_for(ds.recording, compile_vessel(yellowfish_vessel))]
    good = evaluate(yellowfish_vessel, preps)
    wrong = replace(yellowfish_vessel, damping=replace(yellowfish_vessel.damping, Xuu=-12.0, Nr=-60.0))
    bad = evaluate(wrong, preps)
    assert set(good) == {"one_step", "free_run_10s", "free_run_30s", "full"}
    assert good["free_run_10s"]["u"]["r2"] > 0.98 and good["free_run_10s"]["r"]["r2"] > 0.95
    gap = {h: good[h]["u"]["r2"] - bad[h]["u"]["r2"] for h in ("one_step", "free_run_10s")}
    assert gap["free_run_10s"] > 0.02
    # the one-step metric barely tells them apart: why models are judged by free runs
    assert gap["one_step"] < gap["free_run_10s"] / 5


def test_manoeuvres_read_what_the_inputs_ask(yellowfish_vessel):
    pwm = np.array([[1500, 1500], [1700, 1700], [1700, 1300], [1300, 1300], [1700, 1500], [1520, 1480]])
    assert list(manoeuvres(yellowfish_vessel, pwm)) == ["idle", "ahead", "spin", "astern", "turning", "idle"]
    esso = vessel_mod.load("esso_osaka")
    inputs = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, np.radians(20)], [-8.0, 0.0], [0.5, np.radians(35)]])
    assert list(manoeuvres(esso, inputs)) == ["idle", "ahead", "turning", "astern", "idle"]


def test_misfit_by_manoeuvre_adds_up_to_one_minus_r2_and_finds_the_wrong_yaw(yellowfish_vessel):
    ds = generate(yellowfish_vessel, n_segments=3, seed=5, segment_s=(30, 40))
    preps = [prepare_for(ds.recording, compile_vessel(yellowfish_vessel))]
    wrong = replace(yellowfish_vessel, damping=replace(yellowfish_vessel.damping, Nr=-60.0))
    pooled = evaluate(wrong, preps, horizons={"h": 10.0})["h"]
    split = misfit_by_manoeuvre(wrong, preps, 10.0)
    assert split["diverged"] == 0 and sum(g["windows"] for g in split["groups"].values()) == split["windows"]
    for d in ("u", "v", "r"):
        assert sum(g["share"][d] for g in split["groups"].values()) == pytest.approx(1.0 - pooled[d]["r2"], rel=1e-6)
    # a yaw damping twice too strong misses where the boat turns, not where it idles or runs straight
    turning = sum(split["groups"][k]["share"]["r"] for k in ("turning", "spin") if k in split["groups"])
    assert turning > 0.5 * (1.0 - pooled["r"]["r2"])


def test_the_misfit_beyond_what_the_fit_saw(yellowfish_vessel):
    from twin.fit.coverage import Envelope, from_dict
    from twin.fit.evaluate import fitted_envelope, horizon_windows

    ds = generate(yellowfish_vessel, n_segments=3, seed=5, segment_s=(30, 40))
    preps = [prepare_for(ds.recording, compile_vessel(yellowfish_vessel))]
    wrong = replace(yellowfish_vessel, damping=replace(yellowfish_vessel.damping, Xuu=-12.0))
    own = fitted_envelope(yellowfish_vessel, preps)
    assert from_dict(own.to_dict()) == own and own.logs == 1
    # a fit that saw only half the top speed: the faster samples are the ones it extrapolates to
    slow = Envelope({**own.ranges, "u": (own.ranges["u"][0], 0.5 * own.ranges["u"][1])}, own.windows, 10.0, 1)
    split = misfit_by_manoeuvre(wrong, preps, 10.0, fitted=slow)
    b = split["beyond_fit"]
    _, meas = measured(preps, horizon_windows(preps, 10.0, 2.0))
    m = meas[:, 1:]
    beyond_any = np.zeros(m.shape[:2], bool)
    for k, d in enumerate(("u", "v", "r")):
        beyond_any |= (m[..., k] < slow.ranges[d][0]) | (m[..., k] > slow.ranges[d][1])
    fast = m[..., 0] > slow.ranges["u"][1]
    assert b["outside"] == int(beyond_any.sum()) and 0.1 < b["share_of_samples"] < 0.9
    assert fast.sum() > 0.9 * b["outside"]  # nearly all of them for their speed
    # how far they go: the fastest judged sample, beyond a span that saw half of it
    assert b["dofs"]["u"]["above"] == pytest.approx(np.nanmax(m[..., 0])) and b["dofs"]["u"]["reaches"]
    off_u = (m[..., 0] < slow.ranges["u"][0]) | fast
    assert b["dofs"]["u"]["share_of_samples"] == pytest.approx(off_u.sum() / np.isfinite(m).any(-1).sum())
    # a drag too strong misses most at speed: the fast samples carry more than their share of u's misfit
    assert b["share"]["u"] / (1.0 - split["r2"]["u"]) > b["share_of_samples"] + 0.1
    # judged on the log it was fitted on: only the span's own tails lie beyond (1 % at each end of each
    # velocity), said as no reach beyond the fit, and the log is named as the fit's own
    on_own = misfit_by_manoeuvre(wrong, preps, 10.0, fitted=own)["beyond_fit"]
    assert on_own["share_of_samples"] <= 0.06 and not any(x["reaches"] for x in on_own["dofs"].values())
    assert own.sources == (Path(ds.recording.source).name,) or not ds.recording.source
    # judged beside a run the fit did not see, the fit's own windows are left out of what lies beyond
    other = prepare_for(generate(yellowfish_vessel, n_segments=2, seed=6, segment_s=(30, 40)).recording,
                        compile_vessel(yellowfish_vessel))
    mixed = misfit_by_manoeuvre(wrong, preps + [other], 10.0, fitted=own)["beyond_fit"]
    alone = misfit_by_manoeuvre(wrong, [other], 10.0, fitted=own)["beyond_fit"]
    assert mixed["of_new_logs_only"] and mixed["fitted_logs_judged"] == [Path(ds.recording.source).name]
    assert (mixed["samples"], mixed["outside"]) == (alone["samples"], alone["outside"]) and not alone["of_new_logs_only"]
    with pytest.raises(TwinError, match="fitted_on"):
        from_dict({"ranges": {"u": [0.0, 1.0]}})
    with pytest.raises(TwinError, match="counts"):
        from_dict({**own.to_dict(), "windows": {"idle": -1}})
    with pytest.raises(TwinError, match="low ≤ high"):
        from_dict({**own.to_dict(), "ranges": {"u": [1.0, 0.0], "v": [0, 1], "r": [0, 1]}})


def test_the_api_evaluation_says_where_the_twin_misses_and_beyond_what_its_fit_saw(yellowfish_vessel):
    import twin
    from twin.fit.evaluate import fitted_envelope

    ds = generate(yellowfish_vessel, n_segments=2, seed=8, segment_s=(30, 40))
    wrong = replace(yellowfish_vessel, damping=replace(yellowfish_vessel.damping, Xuu=-12.0))
    preps = [prepare_for(ds.recording, compile_vessel(yellowfish_vessel))]
    seen = fitted_envelope(yellowfish_vessel, preps)
    slow = replace(seen, ranges={**seen.ranges, "u": (seen.ranges["u"][0], 0.5 * seen.ranges["u"][1])})
    ev = twin.evaluate(replace(wrong, uncertainty={"fitted_on": slow.to_dict()}), [ds.recording])
    split, pooled = ev.by_manoeuvre, ev.metrics["free_run_10s"]
    for d in ("u", "v", "r"):
        assert sum(g["share"][d] for g in split["groups"].values()) == pytest.approx(1.0 - pooled[d]["r2"], rel=1e-6)
    assert split["beyond_fit"]["share_of_samples"] > 0.1 and ev.to_dict()["by_manoeuvre"] is split
    assert "beyond_fit" not in twin.evaluate(wrong, [ds.recording]).by_manoeuvre  # no record of a fit: none
    logged = twin.evaluate(wrong, [ds.recording], calibrated=False)  # as logged: no offset applied, none shown
    assert logged.metrics == logged.metrics_uncalibrated and not logged.applied and not logged.calibrated
    rows = ev.table()  # a list for code, aligned columns for a person at the prompt
    with_samples = [s for s in ev.scores if s.n]
    assert rows[0]["dof"] == "u" and all(r["n"] for r in rows)  # a horizon longer than the runs has no row
    # the twin's own noise-free run: no compass offset applied, the scores as logged alone, none of
    # them called calibrated
    assert not ev.applied and len(rows) == len(with_samples) and not any(s.calibrated for s in ev.scores)
    text = str(rows).splitlines()
    assert rows.title == text[0] and "predicts" in text[0]  # a title, then the columns
    assert text[1].split() == ["horizon", "dof", "r2", "mae", "n", "calibrated"] and len(text) == len(rows) + 2
    assert f"{pooled['u']['r2']:.4g}" in repr(rows) and "{" not in repr(rows)


def test_manoeuvres_read_a_window_the_same_whatever_else_is_recorded(yellowfish_vessel):
    esso = vessel_mod.load("esso_osaka")
    no_top = replace(esso, thrusters=replace(esso.thrusters, rps_max=None))
    slow = np.array([[0.5, 0.0]] * 3)
    # without a top speed in the vessel "full" is what the recordings reach, taken once for all of them
    assert list(manoeuvres(no_top, slow)) == ["ahead"] * 3
    assert list(manoeuvres(no_top, slow, scale=10.0)) == ["idle"] * 3
    assert list(manoeuvres(no_top, np.vstack([slow, [[10.0, 0.0]]]))[:3]) == ["idle"] * 3
    # a missing input drives nothing, for either kind of vessel
    assert list(manoeuvres(yellowfish_vessel, np.array([[np.nan, np.nan]]))) == ["idle"]
    assert list(manoeuvres(esso, np.array([[np.nan, 0.3]]))) == ["idle"]


class _BlowsUp:
    """A predictor whose first window of every batch diverges."""

    def __init__(self, inner):
        self.inner = inner

    def predict_windows(self, prep, starts, n_steps):
        out = self.inner.predict_windows(prep, starts, n_steps)
        out[0, 1:] = np.inf
        return out


def test_a_diverged_window_is_counted_in_its_group_and_in_no_share(yellowfish_vessel):
    ds = generate(yellowfish_vessel, n_segments=2, seed=6, segment_s=(30, 40))
    preps = [prepare_for(ds.recording, compile_vessel(yellowfish_vessel))]
    split = misfit_by_manoeuvre(_BlowsUp(TwinPredictor(yellowfish_vessel)), preps, 10.0, vessel=yellowfish_vessel)
    assert split["diverged"] >= 1
    assert sum(g["diverged"] for g in split["groups"].values()) == split["diverged"]
    assert sum(g["windows"] for g in split["groups"].values()) == split["windows"]
    for d in ("u", "v", "r"):
        assert sum(g["share"][d] for g in split["groups"].values()) == pytest.approx(1.0 - split["r2"][d], rel=1e-9)
        assert np.isfinite(split["r2"][d])
    with pytest.raises(TwinError):
        misfit_by_manoeuvre(_BlowsUp(TwinPredictor(yellowfish_vessel)), preps, 10.0)


def test_simulation_fit_recovers_the_truth_on_exact_data(yellowfish_vessel):
    effects = ["quadratic_damping=Xuu:0.8", "linear_damping=Nr:0.7", "thrust_gain=1.12"]
    ds = generate(yellowfish_vessel, effects=effects, n_segments=3, seed=1, noise=QUIET, segment_s=(30, 35),
                  manoeuvres=["rc", "forward_varying", "circle_varying"])
    res = simfit.fit(yellowfish_vessel, _truth_preps(ds), ("Xuu", "Nr", "thrust_gain"), window_s=5.0, stride_s=5.0)
    got = {e.name: e.value for e in res.estimates}
    truth = ds.truth_vessel
    assert got["Xuu"] == pytest.approx(truth.damping.Xuu, rel=0.01)
    assert got["Nr"] == pytest.approx(truth.damping.Nr, rel=0.01)
    assert got["thrust_gain"] == pytest.approx(1.12, rel=0.01)
    assert res.cost_after < 1e-6 * res.cost_before
    assert res.vessel.damping.Xuu == pytest.approx(got["Xuu"])


def test_free_start_removes_the_bias_of_noisy_initial_velocities(yellowfish_vessel):
    # exact data except at the samples the windows start from: a fit from those starts bends the yaw
    # dynamics to follow their errors; with the starts estimated, the truth comes back
    ds = generate(yellowfish_vessel, effects=["added_mass=Nrdot:1.5", "linear_damping=Nr:0.7"], n_segments=3,
                  seed=1, noise=QUIET, segment_s=(30, 35), manoeuvres=["rc", "zigzag", "circle_varying"])
    preps = _truth_preps(ds)
    wins = make_windows(preps, 5.0, 6.0)  # a gap between windows: no start is another window's sample
    rng = np.random.default_rng(7)
    spoilt = []
    for i, p in enumerate(preps):
        u, v, r = p.u.copy(), p.v.copy(), p.r.copy()
        for k in (w.start for w in wins if w.rec == i):
            u[k], v[k], r[k] = (u[k], v[k], r[k]) + rng.normal(0.0, 0.05, 3)
        spoilt.append(replace(p, u=u, v=v, r=r))
    truth = ds.truth_vessel
    fits = {fs: simfit.fit(yellowfish_vessel, spoilt, ("Nrdot", "Nr"), window_s=5.0, stride_s=6.0, free_start=fs)
            for fs in (False, True)}
    got = {fs: {e.name: e.value for e in f.estimates} for fs, f in fits.items()}
    assert got[True]["Nrdot"] == pytest.approx(truth.added_mass.Nrdot, rel=0.005)
    assert got[True]["Nr"] == pytest.approx(truth.damping.Nr, rel=0.005)
    assert fits[True].cost_after < 1e-3 * fits[False].cost_after
    assert abs(got[False]["Nrdot"] / truth.added_mass.Nrdot - 1) > 0.02


@pytest.mark.parametrize("free_start", [False, True])
def test_the_jacobian_reuses_the_runs_of_the_point_just_evaluated(yellowfish_vessel, free_start):
    # a least-squares solver asks for the Jacobian where it has just had the residuals: the point's own
    # runs (with free_start, four) are not rolled out again, and the Jacobian is the same to the bit
    from twin.effects.coefficients import coefficients

    ds = generate(yellowfish_vessel, n_segments=2, seed=3, noise=QUIET, segment_s=(25, 30))
    preps = _truth_preps(ds)
    wins = make_windows(preps, 5.0, 5.0)
    table = coefficients(yellowfish_vessel)
    params = [table["Nr"], table["Xu"]]
    fresh = Objective(yellowfish_vessel, params, preps, wins, free_start=free_start)
    x = fresh.x_prior * 1.1
    J_fresh = fresh.jacobian(x)
    used = Objective(yellowfish_vessel, params, preps, wins, free_start=free_start)
    used.residuals(x)
    before = used.evaluations
    J_used = used.jacobian(x)
    assert used.evaluations - before == len(params)  # only the neighbours
    assert fresh.evaluations == len(params) + 1
    np.testing.assert_array_equal(J_used, J_fresh)
    np.testing.assert_array_equal(used.residuals(x), fresh.residuals(x))
    used.sigma = used.sigma * 2.0  # rescaled residuals, not the kept runs (the free start's regulariser: 1e-6)
    np.testing.assert_allclose(used.residuals(x)[: used.n_data] * 2.0, fresh.residuals(x)[: fresh.n_data], atol=1e-5)


def test_a_line_search_point_is_not_rolled_out_again(yellowfish_vessel):
    # residuals_at's trials are kept: the residuals and the Jacobian at the point a line search settles
    # on run only the Jacobian's neighbours, a scan's trial at its centre runs nothing, and each
    # point's residuals are the same to the bit as those of the point alone
    from twin.effects.coefficients import coefficients

    ds = generate(yellowfish_vessel, n_segments=2, seed=3, noise=QUIET, segment_s=(25, 30))
    preps = _truth_preps(ds)
    wins = make_windows(preps, 5.0, 5.0)
    table = coefficients(yellowfish_vessel)
    params = [table["Nr"], table["Xu"]]
    obj = Objective(yellowfish_vessel, params, preps, wins)
    trials = [obj.x_prior * f for f in (1.0, 1.1, 1.2)]
    kept = obj.residuals_at(trials)
    assert obj.evaluations == 3
    alone = Objective(yellowfish_vessel, params, preps, wins)
    for x, r in zip(trials, kept):
        np.testing.assert_array_equal(r, alone.residuals(x)[: alone.n_data])
    np.testing.assert_array_equal(obj.residuals(trials[1])[: obj.n_data], kept[1])
    obj.jacobian(trials[1])
    assert obj.evaluations == 3 + len(params)
    again = obj.residuals_at([trials[2], obj.x_prior * 1.3])
    assert obj.evaluations == 3 + len(params) + 1
    np.testing.assert_array_equal(again[0], kept[2])


def test_a_parameter_the_data_cannot_excite_is_named_not_returned(yellowfish_vessel):
    # forward throttle only: nothing ever runs a thruster in reverse
    ds = generate(yellowfish_vessel, n_segments=2, seed=1, noise=QUIET, segment_s=(25, 30),
                  manoeuvres=["forward_constant", "forward_varying"])
    res = simfit.fit(yellowfish_vessel, _truth_preps(ds), ("Xuu", "reverse_scale"), window_s=5.0)
    rev = next(e for e in res.estimates if e.name == "reverse_scale")
    assert not rev.identifiable and rev.sigma is None and "excite" in rev.note
    assert res.vessel.thrusters.reverse == yellowfish_vessel.thrusters.reverse


def test_a_coefficient_the_data_push_beyond_its_physical_range_is_said_to_be_on_its_bound(yellowfish_vessel):
    # the truth turns with half the yaw damping; a fit free only in the speed-proportional yaw damping
    # N_ur (a damping: ≤ 0) would need it positive, so it stops on 0, which is a wall, not a measurement
    ds = generate(yellowfish_vessel, effects=["linear_damping=Nr:0.5"], n_segments=3, seed=2, noise=QUIET,
                  segment_s=(30, 35), manoeuvres=["rc", "zigzag", "circle_varying"])
    res = simfit.fit(yellowfish_vessel, _truth_preps(ds), ("Nur", "Xuu"), window_s=5.0, prior_weight=1.0)
    est = {e.name: e for e in res.estimates}
    assert est["Nur"].on_bound and est["Nur"].value == pytest.approx(0.0, abs=1e-3)
    assert "on the bound" in est["Nur"].note and est["Nur"].to_dict()["on_bound"] is True
    assert not est["Xuu"].on_bound and "on_bound" not in est["Xuu"].to_dict()


def test_near_bound_tells_on_from_within_sigma_from_clear():
    class Obj:  # the two things _near_bound reads of an objective
        scale = np.array([10.0, 10.0, 10.0])

        @staticmethod
        def bounds():
            return np.array([-1e3, -1e3, -1e3]), np.array([0.0, 0.0, 0.0])

    x = np.array([-1e-9, -0.005, -0.5])  # on the bound, 0.05 from it (σ 0.2), 5 from it (σ 0.2)
    cov = np.diag([0.2, 0.2, 0.2]) ** 2
    got = simfit._near_bound(Obj(), x, cov)
    assert got[0] == (0.0, True) and got[1] == (0.0, False) and got[2] is None


def test_scale_needs_an_anchor(yellowfish_vessel):
    ds = generate(yellowfish_vessel, n_segments=1, seed=1, noise=QUIET, segment_s=(20, 21))
    with pytest.raises(TwinError, match="anchor"):
        simfit.fit(yellowfish_vessel, _truth_preps(ds), ("Xudot", "thrust_gain"))
    with pytest.raises(TwinError, match="unknown parameter"):
        simfit.fit(yellowfish_vessel, _truth_preps(ds), ("Xq",))


def test_sensor_noise_profiles_are_what_they_say():
    assert PROFILES["none"] == SensorNoise(0.0, 0.0, 60.0, 0.0)
    assert PROFILES["realistic"].gnss_dt_s == 0.2 and PROFILES["realistic"].heading_dt_s == 0.02


def test_a_diverging_segment_is_named(monkeypatch, yellowfish_vessel):
    """A batch twin that diverges stops the dataset with the segment and manoeuvre named."""
    import twin.synth.dataset as dataset
    from twin.engine.batch import Runs

    def diverging(compiled, inputs, durations_s, **kwargs):
        return Runs([None] * len(inputs), [(0, kwargs["start_s"][0] + 12.5)])

    monkeypatch.setattr(dataset, "simulate_many", diverging)
    with pytest.raises(TwinError, match=r"segment 1 \(rc\) at 7\.50 s after its logged start"):
        generate(yellowfish_vessel, n_segments=1, seed=4, noise=QUIET, manoeuvres=["rc"], segment_s=(20, 25))


def test_needed_groups_are_those_whose_return_to_the_prior_hurts_left_out_runs(yellowfish_vessel):
    from twin.fit.crossval import CrossValidation, RunScore
    from twin.ident.identify import Choice, Identification, format_needed

    def choice(label, weight, groups, cost):
        return Choice(label, weight, groups, CrossValidation(label, [RunScore("run", {}, cost)]))

    every = ("surge", "yaw", "coupling")
    ident = Identification(yellowfish_vessel, yellowfish_vessel, None, choices=[
        choice("beliefs ×1", 1.0, every, 100.0), choice("beliefs ×0.1", 0.1, every, 120.0),
        choice("beliefs ×1 without surge", 1.0, ("yaw", "coupling"), 104.0),
        choice("beliefs ×1 without yaw", 1.0, ("surge", "coupling"), 480.0),
        choice("beliefs ×1 without coupling", 1.0, ("surge", "yaw"), 130.0),
        choice("beliefs ×0.1 without yaw", 0.1, ("surge", "coupling"), 900.0),  # another weight: not compared
        choice("beliefs ×1 without surge without coupling", 1.0, ("yaw",), 700.0)])  # a later round
    assert ident.needed() == [("yaw", pytest.approx(4.8)), ("coupling", pytest.approx(1.3))]
    assert format_needed(ident).startswith("the left-out runs need: yaw (left-out cost ×4.80")
    assert Identification(yellowfish_vessel, yellowfish_vessel, None).needed() == []


def test_identify_fits_the_thrusts_answer_to_the_logged_pack(yellowfish_vessel):
    """Logs that record their battery offer the group 'pack voltage': the exponent of (V/V_ref)^k,
    V_ref the logs' fullest pack; a log without one withdraws it, in one line."""
    from twin.ident.identify import identify

    ds = generate(yellowfish_vessel, effects=["supply_voltage=2,16"], n_segments=4, seed=3, noise=PROFILES["none"],
                  segment_s=(35, 40), manoeuvres=["rc", "forward_varying", "circle_varying"])
    # beliefs worth a hundredth of their default: the noise-free data speak, not the belief's k = 1 ± 1.5
    result = identify([ds.recording], yellowfish_vessel, params=("supply_exponent",), prior_weights=(0.01,),
                      calibrated=False, max_evaluations=8)
    t = result.vessel.thrusters
    assert t.supply_ref_v == pytest.approx(16.0, abs=0.02) and t.supply_exponent == pytest.approx(2.0, abs=0.25)
    plain = generate(yellowfish_vessel, n_segments=3, seed=4, noise=PROFILES["none"], segment_s=(35, 40),
                     manoeuvres=["rc"])
    with pytest.raises(TwinError, match="pack voltage"):
        identify([ds.recording, plain.recording], yellowfish_vessel, groups=("pack voltage",), prior_weights=(1.0,))


class _LinearObjective:
    """The least an objective offers jackknife_vessels: two data per window, a line y = a + b·x."""

    def __init__(self, windows: int):
        self.n_data = 2 * windows
        self.x_prior = np.zeros(2)

    def window_index(self):
        return np.repeat(np.arange(self.n_data // 2), 2)

    def bounds(self):
        return np.full(2, -np.inf), np.full(2, np.inf)

    def vessel(self, x):
        return x


def test_a_left_out_group_with_no_fitted_window_gets_the_fit_on_every_window():
    """A log whose windows are all idle is judged, not fitted on: its fold's twin is the whole fit,
    and every other fold's leaves its own group out (a refusal here once stopped identify on two logs)."""
    rng = np.random.default_rng(3)
    obj = _LinearObjective(windows=6)
    xs = rng.uniform(-1, 1, obj.n_data)
    jac = np.column_stack([np.ones(obj.n_data), xs])
    truth = np.array([0.5, -2.0])
    residual = -(jac @ truth) + 0.1 * rng.standard_normal(obj.n_data)  # r(0) = J·0 − y
    fit_groups = np.array([0, 0, 0, 1, 1, 1])  # the fitted windows' groups; group 2 (idle) has none
    twins = jackknife_vessels(obj, np.zeros(2), jac, residual, fit_groups, folds=each_folds(np.array([0, 1, 2])))
    assert len(twins) == 3
    whole = np.linalg.lstsq(jac, -residual, rcond=None)[0]
    assert np.allclose(twins[2], whole)
    without_first = np.linalg.lstsq(jac[6:], -residual[6:], rcond=None)[0]
    assert np.allclose(twins[0], without_first)
    assert not np.allclose(twins[0], whole)


def test_a_free_run_that_runs_away_is_scored_as_diverged_and_the_table_says_so(yellowfish_vessel):
    """A candidate whose free runs grow to 1e9 m/s stays below MuJoCo's own bound; scored by its
    finite error it would show a cost of about 1e21 and no reason."""
    from twin.fit.crossval import CrossValidation, score_run
    from twin.ident.identify import Choice, Identification, format_choices

    meas = np.zeros((2, 5, 3))
    sane = score_run("calm", meas + 0.1, meas, np.ones(3))
    wild = meas + 0.1
    wild[1, 3:, 0] = 1e9
    runaway = score_run("wild", wild, meas, np.ones(3))
    assert runaway.metrics["u"]["diverged"] == 2 and runaway.metrics["u"]["r2"] is None
    assert runaway.cost == pytest.approx(100.0 * 2 + 0.01 * 28) and sane.cost == pytest.approx(0.01 * 30)
    ident = Identification(yellowfish_vessel, yellowfish_vessel, None, choices=[
        Choice("beliefs ×1", 1.0, ("surge",), CrossValidation("beliefs ×1", [sane, runaway]))])
    row = format_choices(ident).splitlines()[-1]
    assert "ran away on 1 of 2 left-out runs" in row and "e+2" not in row


def test_the_fits_model_of_the_measurement_smooths_over_ground_as_the_estimator_does(tmp_path):
    """A turning BlueBoat's true velocities, seen through fit.windows.as_measured, are the velocities
    prepare() measures from its own logged track: its sway within 5 mm/s RMS, where smoothing the
    body-frame sway instead (the ground track's turn left out) misses by more than twice as much,
    and u and r within a third of the unsmoothed prediction's difference."""
    from twin.fit.windows import _past, _smoothed, as_measured
    from twin.prepare import prepare
    from twin.simulation import simulate_run

    sim = simulate_run("blueboat", scenario="random", duration_s=120.0, seed=1)
    sim.write(tmp_path / "run.csv")
    prep = prepare(read_recording(tmp_path / "run.csv"), window_s=1.0, heading_window_s=0.5)
    wins = make_windows([prep], 10.0, 5.0, min_length_s=10.0)
    true = np.stack([np.interp(prep.t, sim.run.t, sim.run.nu[:, k]) for k in range(3)], axis=-1)
    nu = np.stack([true[w.start: w.start + w.n + 1] for w in wins])
    meas = np.stack([np.stack([prep.u, prep.v, prep.r], axis=-1)[w.start: w.start + w.n + 1] for w in wins])
    seen = as_measured(nu, [prep], wins)
    half = int(round(0.5 / prep.settings.grid_dt))
    body = _smoothed(nu[..., :2], _past([prep], wins, half)[..., :2], 1.0, prep.settings.grid_dt)
    rms = lambda x: float(np.sqrt(np.nanmean(x[:, 1:] ** 2)))  # noqa: E731
    assert np.degrees(np.abs(sim.run.nu[:, 2])).max() > 20.0  # the run turns hard enough to tell
    assert rms(seen[..., 1] - meas[..., 1]) < 0.005
    assert rms(body[..., 1] - meas[..., 1]) > 2 * rms(seen[..., 1] - meas[..., 1])
    for k in (0, 2):  # u and r: a third of the raw prediction's difference or less, the window's end included
        assert rms(seen[..., k] - meas[..., k]) < rms(nu[..., k] - meas[..., k]) / 3


def test_a_horizon_with_no_window_is_said_why_its_row_is_empty():
    from twin.fit.evaluate import format_metrics

    none = {d: {"r2": None, "mae": None, "n": 0} for d in "uvr"}
    some = {d: {"r2": 0.9, "mae": 0.01, "n": 40} for d in "uvr"}
    text = format_metrics({"one_step": some, "free_run_10s": none, "free_run_30s": none})
    assert text.splitlines()[-1] == ("-: no window of free_run_10s, free_run_30s fits in the recording: every "
                                     "stretch without a dropout (or the whole log) is shorter")
    assert "no window" not in format_metrics({"one_step": some})


def test_the_parameter_table_keeps_its_columns_for_long_names(yellowfish_vessel):
    """An MMG name as long as mmg_gamma_minus must not push its row's numbers out from under their heads."""
    from twin.fit.objective import Estimate
    from twin.ident.identify import format_estimates

    estimates = [Estimate("Xuu", "kg/m", 1.0, 2.0, 0.1, True),
                 Estimate("mmg_gamma_minus", "-", 0.395, 0.41, None, False, "kept at the prior")]
    text = format_estimates(simfit.FitResult(yellowfish_vessel, estimates, 2.0, 1.0, 4, 10, 1.0))
    head, _, *rows = text.splitlines()[:4]
    for row in rows:  # every value ends where its head ends
        assert row.index(" kg/m" if "Xuu" in row else " -    ") == head.index(" unit")
        assert row[:head.index("identified") + len("identified")].endswith(("2", "0.41"))


def test_a_span_near_zero_keeps_its_digits():
    """A ship's yaw rate spans a few hundredths of a rad/s: two decimals would print it as 0.00."""
    from twin.fit.coverage import span_text

    assert span_text({"r": (-0.004, 0.05)}) == "r -0.23..+2.86 °/s"
    assert span_text({"r": (-0.0005, 0.001)}) == "r -0.029..+0.057 °/s"
    assert span_text({"u": (-0.12, 1.5)}) == "u -0.12..+1.50 m/s"


def test_misfit_by_state_adds_up_to_one_minus_r2_and_finds_a_drag_too_strong_at_speed(yellowfish_vessel):
    from twin.fit.evaluate import misfit_by_state

    ds = generate(yellowfish_vessel, n_segments=3, seed=5, segment_s=(30, 40))
    preps = [prepare_for(ds.recording, compile_vessel(yellowfish_vessel))]
    wrong = replace(yellowfish_vessel, damping=replace(yellowfish_vessel.damping, Xuu=-12.0))
    pooled = evaluate(wrong, preps, horizons={"h": 10.0})["h"]
    speed = np.hypot(preps[0].u, preps[0].v)
    edge = float(np.median(speed))
    bands = misfit_by_state(wrong, preps, 10.0, "speed_m_s", (edge,))
    assert [b.label for b in bands] == [f"< {edge:.3g} m/s", f"≥ {edge:.3g} m/s"]
    assert sum(b.samples for b in bands) == pytest.approx(1.0)
    for d in ("u", "v", "r"):
        assert sum(b.share[d] for b in bands) == pytest.approx(1.0 - pooled[d]["r2"], rel=1e-6)
    slow, fast = bands
    # a quadratic drag too strong slows the twin where it runs fast: more of u's misfit there, and the
    # vessel moves more than the twin (gain above 1)
    assert fast.share["u"] > 2.0 * slow.share["u"] and fast.gain["u"] > 1.02
    # the twin's own shape at the wrong size: the two still move together
    assert fast.correlation["u"] > 0.95
    from twin.fit.evaluate import _correlation

    rng = np.random.default_rng(4)
    x = rng.normal(size=200)
    y = 0.3 * x + rng.normal(size=200)  # loosely related: a correlation near 0.3, not 1
    assert _correlation(x, y) == pytest.approx(np.corrcoef(x, y)[0, 1]) and 0.1 < _correlation(x, y) < 0.6
    assert _correlation(x, -x) == pytest.approx(-1.0) and _correlation(x, np.ones(200)) is None
    # the twin itself misses nowhere
    own = misfit_by_state(yellowfish_vessel, preps, 10.0, "speed_m_s", (edge,))
    assert max(b.share["u"] for b in own) < 0.05 and all(abs(b.gain["u"] - 1.0) < 0.02 for b in own)
    with pytest.raises(TwinError, match="unknown state"):
        misfit_by_state(wrong, preps, 10.0, "heave", (1.0,))
    pwm = misfit_by_state(wrong, preps, 10.0, "input_0", (1625.0, 1750.0))  # PWM in whole µs, never 1.75e+03
    assert pwm and {b.label for b in pwm} <= {"< 1625 µs", "1625 to 1750 µs", "≥ 1750 µs"}


def test_a_propellers_rest_is_timed_from_when_it_stopped_within_its_segment():
    from types import SimpleNamespace

    from twin.fit.evaluate import recording_states

    t = np.arange(8) * 0.5
    n = np.array([5.0, 0.0, 0.5, -0.2, 6.0, 0.0, 0.0, 0.0])
    prep = SimpleNamespace(t=t, segment=np.array([0, 0, 0, 0, 0, 0, 1, 1]), pwm=np.column_stack([n, np.zeros(8)]),
                           u=np.array([0.3] * 6 + [-0.3, 0.0]), v=np.array([0.4] * 6 + [-0.4, 0.5]),
                           r=np.full(8, -0.1))
    states = recording_states(prep)
    # the drift angle |atan2(v, |u|)|: the same ahead and astern, 90° broadside
    np.testing.assert_allclose(states["drift_rad"], [np.arctan2(0.4, 0.3)] * 7 + [np.pi / 2])
    np.testing.assert_allclose(states["input_0_rest_s"], [0, 0, 0.5, 1.0, 0, 0, 0, 0.5])
    np.testing.assert_allclose(states["speed_m_s"], 0.5)
    np.testing.assert_allclose(states["yaw_rate_rad_s"], 0.1)


def test_a_ship_is_offered_every_coefficient_but_a_pwm_thrusters(yellowfish_vessel):
    boat, ship = set(coefficients(yellowfish_vessel)), set(coefficients(vessel_mod.load("esso_osaka")))
    assert boat - ship == set(PWM_THRUSTER_TERMS) and not ship & set(PWM_THRUSTER_TERMS)


def test_identify_says_when_its_left_out_runs_cannot_tell_the_options_apart():
    """Options whose left-out costs differ by under 1 % are said to rest on nothing (a short log's
    table that decides nothing); a spread of 5 % is a choice, said as none."""
    from types import SimpleNamespace

    from twin.fit.crossval import CrossValidation, RunScore
    from twin.ident.identify import format_choices

    def cv(label, cost):
        metrics = {d: {"r2": 0.5, "mae": 0.1} for d in "uvr"}
        return CrossValidation(label, runs=[RunScore("a part 1", metrics, cost)])

    def ident(costs):
        choices = [SimpleNamespace(label=f"beliefs ×{k}", cv=cv(f"beliefs ×{k}", c)) for k, c in enumerate(costs)]
        return SimpleNamespace(prior_cv=None, choices=choices,
                               chosen=SimpleNamespace(cv=choices[0].cv, free_groups=("surge",)))

    assert "the choice rests on nothing" in format_choices(ident([1439.0, 1440.0, 1442.0]))
    assert "the choice rests on nothing" not in format_choices(ident([1439.0, 1511.0]))


def test_each_velocity_weighed_by_its_own_misfit_keeps_a_sway_the_twin_cannot_read_out_of_the_yaw(yellowfish_vessel):
    # exact data but the sway read with a slow error of its own (a sensor's, which no coefficient
    # answers): scaled by its measured spread the sway's error bends the yaw coefficients; scaled by
    # each velocity's own misfit at a first fit (identify's rule), the yaw comes back
    from twin.ident.identify import MIN_MISFIT_SHARE, own_misfit_sigma

    ds = generate(yellowfish_vessel, effects=["linear_damping=Nr:0.7", "added_mass=Nrdot:1.5"], n_segments=3,
                  seed=1, noise=QUIET, segment_s=(30, 35), manoeuvres=["rc", "zigzag", "circle_varying"])
    rng = np.random.default_rng(3)
    spoilt = [replace(p, v=p.v + 0.3 * np.convolve(rng.normal(0.0, 1.0, len(p.v)), np.ones(20) / 20, "same"))
              for p in _truth_preps(ds)]
    names = ("Nr", "Nrdot", "Yv", "Yur")
    spread = simfit.fit(yellowfish_vessel, spoilt, names, window_s=5.0, stride_s=5.0, prior_weight=0.01)
    sigma = own_misfit_sigma(spread)
    obj = spread.objective
    assert sigma == pytest.approx(obj.sigma * np.maximum(obj.dof_rms(spread.x), MIN_MISFIT_SHARE))
    assert sigma[1] / obj.sigma[1] > 2 * max(sigma[0] / obj.sigma[0], sigma[2] / obj.sigma[2])  # the sway's the worst
    own = simfit.fit(yellowfish_vessel, spoilt, names, window_s=5.0, stride_s=5.0, prior_weight=0.01,
                     dof_sigma=sigma, start=spread.vessel)
    truth = ds.truth_vessel.added_mass.Nrdot

    def error(fit):
        return abs(next(e.value for e in fit.estimates if e.name == "Nrdot") / truth - 1)
    assert error(spread) > 0.15
    assert error(own) < 0.10


def test_a_coefficient_moved_beyond_its_belief_is_flagged_as_standing_in_for_missing_physics(yellowfish_vessel):
    # yaw added inertia six times the prior's (outside a belief of a factor of 2: 2.6 σ), the yaw damping
    # 0.7 of it (inside its factor of 3): the fit follows both; only the first is flagged
    from twin.fit.objective import STAND_IN_SIGMAS

    ds = generate(yellowfish_vessel, effects=["linear_damping=Nr:0.7", "added_mass=Nrdot:6"], n_segments=3,
                  seed=1, noise=QUIET, segment_s=(30, 35), manoeuvres=["rc", "zigzag", "circle_varying"])
    fit = simfit.fit(yellowfish_vessel, _truth_preps(ds), ("Nr", "Nrdot"), window_s=5.0, stride_s=5.0,
                     prior_weight=0.01)
    est = {e.name: e for e in fit.estimates}
    assert est["Nrdot"].value / yellowfish_vessel.added_mass.Nrdot > 4.0
    assert est["Nrdot"].from_prior_sigmas >= STAND_IN_SIGMAS and est["Nrdot"].stand_in
    assert "stands in for something the twin's form lacks" in est["Nrdot"].note and not est["Nrdot"].held_by_belief
    assert est["Nr"].from_prior_sigmas < 1.0 and not est["Nr"].stand_in
    assert "stands in" not in est["Nr"].note
    assert est["Nrdot"].to_dict()["from_prior_sigmas"] == pytest.approx(est["Nrdot"].from_prior_sigmas)


def test_a_fit_continued_from_another_belief_weight_runs_nothing_at_its_start(yellowfish_vessel):
    # the data's rows do not depend on the belief weight: a fit at another weight that starts from a
    # finished fit takes its residuals and Jacobian there, and ends where a start from its vessel ends
    ds = generate(yellowfish_vessel, effects=["linear_damping=Nr:0.7"], n_segments=2, seed=2, noise=QUIET,
                  segment_s=(30, 35), manoeuvres=["rc", "zigzag"])
    preps = _truth_preps(ds)
    first = simfit.fit(yellowfish_vessel, preps, ("Nr", "Xuu"), window_s=5.0, stride_s=5.0, prior_weight=1.0)
    kw = dict(window_s=5.0, stride_s=5.0, prior_weight=0.01, max_evaluations=4)
    from_result = simfit.fit(yellowfish_vessel, preps, ("Nr", "Xuu"), start=first, **kw)
    from_vessel = simfit.fit(yellowfish_vessel, preps, ("Nr", "Xuu"), start=first.vessel, **kw)
    assert from_result.n_evaluations < from_vessel.n_evaluations
    for a, b in zip(from_result.estimates, from_vessel.estimates):
        assert a.value == pytest.approx(b.value, rel=1e-6)
    # what it is given are the rows the new objective itself makes at that point
    obj = from_result.objective
    fresh = Objective(obj.prior, obj.params, obj.data, obj.windows, obj.cache, obj.settle_s,
                             free_start=obj.free_start)
    fresh.sigma = obj.sigma
    n = obj.n_data
    assert np.array_equal(fresh.residuals(first.x)[:n], first.objective.residuals(first.x)[:n])
    assert np.array_equal(fresh.jacobian(first.x)[:n], first.jacobian[:n])
    # each velocity scaled otherwise: the start weighs every window's fitted start otherwise, and the
    # rows are run again (its vessel is the start)
    sigma = first.objective.sigma * np.array([0.5, 3.0, 0.8])
    scaled = simfit.fit(yellowfish_vessel, preps, ("Nr", "Xuu"), start=first, dof_sigma=sigma, **kw)
    rerun = simfit.fit(yellowfish_vessel, preps, ("Nr", "Xuu"), start=first.vessel, dof_sigma=sigma, **kw)
    assert scaled.n_evaluations == rerun.n_evaluations and scaled.estimates == rerun.estimates
    # another set of coefficients: the finished fit is only a start (its vessel), nothing is taken over
    other = simfit.fit(yellowfish_vessel, preps, ("Nr",), start=first, **kw)
    plain = simfit.fit(yellowfish_vessel, preps, ("Nr",), start=first.vessel, **kw)
    assert other.estimates[0].value == plain.estimates[0].value and other.n_evaluations == plain.n_evaluations


def test_a_vessel_file_keeps_its_stand_ins_and_refuses_a_damaged_entry(yellowfish_vessel, tmp_path):
    entry = {"name": "Nrdot", "unit": "kg m2", "value": -4.1, "prior": -0.685, "from_prior_sigmas": 2.58}
    block = {"coordinates": [{"name": "Nrdot", "log": True, "sign": -1.0}], "mean": [float(np.log(4.1))],
             "covariance": [[0.01]], "stand_ins": [entry]}
    path = tmp_path / "flagged.json"
    vessel_mod.save(replace(yellowfish_vessel, added_mass=replace(yellowfish_vessel.added_mass, Nrdot=-4.1),
                            uncertainty=block), path)
    assert vessel_mod.load(str(path)).uncertainty["stand_ins"] == [entry]
    data = json.loads(path.read_text())
    data["uncertainty"]["stand_ins"] = [{**entry, "value": "large"}]
    path.write_text(json.dumps(data))
    with pytest.raises(TwinError, match="uncertainty.stand_ins needs"):
        vessel_mod.load(str(path))


def test_the_weights_fitted_side_by_side_give_what_one_after_another_gives(yellowfish_vessel, monkeypatch):
    """identify fits its beliefs' other weights in threads (SIDE_BY_SIDE) on one model cache: every
    coefficient and every left-out cost as fitted one after another."""
    import twin.ident.identify as ident_mod

    ds = generate(yellowfish_vessel, effects=["linear_damping=Nr:0.7"], n_segments=4, seed=5,
                  noise=PROFILES["realistic"], segment_s=(40, 45), manoeuvres=["zigzag", "circle_varying"])
    recs = [ds.recording]

    def run(side_by_side):
        monkeypatch.setattr(ident_mod, "SIDE_BY_SIDE", side_by_side)
        got = ident_mod.identify(recs, yellowfish_vessel, groups=("yaw", "surge"), prior_weights=(0.1, 1.0, 10.0),
                                 max_evaluations=6)
        return ({c.label: c.cv.cost for c in got.choices},
                {e.name: e.value for c in [got.fit] for e in c.estimates})

    apart, together = run(1), run(3)
    assert len(apart[0]) >= 3 and apart == together


def test_belief_weights_that_print_alike_are_refused_before_any_fit(yellowfish_vessel):
    from twin.ident.identify import identify

    ds = generate(yellowfish_vessel, n_segments=1, seed=2, noise=QUIET, segment_s=(20, 21))
    with pytest.raises(TwinError, match="must differ in their first six digits: 0.333333 is given more than once"):
        identify([ds.recording], yellowfish_vessel, prior_weights=(0.3333333, 0.33333333, 1.0))
