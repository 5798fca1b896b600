"""Many twins at once (mujoco.rollout + native callback) against one-by-one mj_step."""
from dataclasses import replace

import mujoco
import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin.verify.crosscheck import TERM_ENV
from twin.engine import batch, divergence, native
from twin.engine.mjcf import CompiledVessel, compile_vessel
from twin.engine.sim import simulate
from twin.errors import TwinError
from twin.drive import InputSeries
from twin.physics.damping import Damping
from twin.physics.hydrodynamics import Terms

NSTEP = 300


@pytest.fixture(scope="module")
def compiled():
    return {name: compile_vessel(vessel_mod.load(name)) for name in ("yellowfish", "cybership1")}


@pytest.fixture(autouse=True)
def _no_log_litter(tmp_path, monkeypatch):
    """MuJoCo appends divergence warnings to MUJOCO_LOG.TXT in the working directory unless the
    twin switches its log off while stepping (engine/divergence.py): none may appear."""
    monkeypatch.chdir(tmp_path)
    yield
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists()


def _one_by_one(model, state0, controls) -> np.ndarray:
    """The reference: one MjData, mj_step per control, the full state after each step."""
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, state0, batch.FULL)
    out = np.empty((len(controls), len(state0)))
    with native.installed_native(), divergence.quiet_log():  # as the twin steps: no MUJOCO_LOG.TXT
        for k, u in enumerate(controls):
            data.ctrl[:] = u
            mujoco.mj_step(model, data)
            mujoco.mj_getState(model, data, out[k], batch.FULL)
    return out


def _twins(compiled, bad: bool = False):
    """Several parameter sets of yellowfish (terms, current/wind, damping) and a cybership1."""
    yf = compiled["yellowfish"]
    env = CompiledVessel(replace(yf.vessel, environment=TERM_ENV), yf.model, yf.geometry)
    hydros = [yf.hydro(), env.hydro(), env.hydro(Terms(added_mass=False)),
              replace(yf.hydro(), damping=replace(yf.vessel.damping, Xu=-6.0, Nr=-9.0))]
    if bad:
        hydros.insert(2, replace(yf.hydro(), damping=Damping(Xu=80.0, Yv=80.0, Nr=80.0)))
    return batch.models_for(yf, hydros) + [native.with_native_params(compiled["cybership1"])]


def _inputs(models, seed=0):
    rng = np.random.default_rng(seed)
    states = np.array([batch.initial_state(m, rng.uniform(-2, 2, 3), rng.uniform(-0.5, 0.5, 3)) for m in models])
    controls = np.repeat(rng.uniform(-10.0, 40.0, (len(models), NSTEP // 20, 2)), 20, axis=1)
    return states, controls


@pytest.mark.parametrize("nthread", [1, 2])
def test_batch_is_bit_identical_to_one_by_one(compiled, nthread):
    models = _twins(compiled)
    states0, controls = _inputs(models)
    states, diverged = batch.rollout(models, states0, controls, nthread=nthread)
    assert diverged == []
    assert states.shape == (len(models), NSTEP, batch.state_size(models[0]))
    for i, m in enumerate(models):
        assert np.array_equal(states[i], _one_by_one(m, states0[i], controls[i])), i
    assert not np.array_equal(states[0], states[3])  # different parameters, different twins


def test_rollouts_share_their_pool_and_data_and_stay_bit_identical(compiled):
    """The kept MjData of a rollout in which a twin blew up (MuJoCo reset it) serve the next one."""
    bad = _twins(compiled, bad=True)
    states0, controls = _inputs(bad, seed=1)
    assert [i for i, _ in batch.rollout(bad, states0, controls, nthread=2)[1]] == [2]
    kept = batch._pool(bad[0], 2)
    models = _twins(compiled)
    states0, controls = _inputs(models, seed=2)
    states, diverged = batch.rollout(models, states0, controls, nthread=2)
    assert diverged == [] and batch._pool(models[0], 2)[1] is kept[1]
    for i, m in enumerate(models):
        assert np.array_equal(states[i], _one_by_one(m, states0[i], controls[i])), i


def test_a_diverging_twin_is_reported_and_the_others_kept(compiled):
    models = _twins(compiled, bad=True)
    states0, controls = _inputs(models, seed=1)
    states, diverged = batch.rollout(models, states0, controls, nthread=2)
    assert [i for i, _ in diverged] == [2]
    t_bad = diverged[0][1]
    h = models[2].opt.timestep
    assert 0 < t_bad < NSTEP * h
    k = int(round(t_bad / h)) - 1  # first bad sample
    assert np.all(np.isnan(states[2, k:])) and np.all(np.isfinite(states[2, :k]))
    reference = _one_by_one(models[2], states0[2], controls[2])
    assert np.array_equal(states[2, :k], reference[:k])
    assert batch._first_bad(reference, states0[2, 0]) == k  # alone, it fails at the same step
    for i in (0, 1, 3, 4, 5):
        assert np.array_equal(states[i], _one_by_one(models[i], states0[i], controls[i])), i


def test_one_vessel_for_all_twins(compiled):
    cv = compiled["cybership1"]
    model = native.with_native_params(cv)
    states0 = np.array([batch.initial_state(model, nu0=(0.1 * i, 0.0, 0.0)) for i in range(3)])
    controls = np.full((3, 50, 2), 1.0)
    by_vessel, _ = batch.rollout(cv, states0, controls, nthread=2)
    by_model, _ = batch.rollout(model, states0, controls, nthread=1)
    assert np.array_equal(by_vessel, by_model)


def test_controls_from_inputs_reproduce_the_python_simulator(compiled):
    cv = compiled["yellowfish"]
    series = InputSeries(np.array([0.0, 3.0, 6.0]), np.array([[30.0, 10.0], [-5.0, 20.0], [40.0, 40.0]]), "thrust")
    h = cv.model.opt.timestep
    nstep = int(round(10.0 / h))
    run = simulate(cv, series, 10.0, sample_dt_s=h, nu0=(0.5, 0.1, 0.0))
    model = native.with_native_params(cv)
    controls = batch.thrust_controls_from_inputs(cv.vessel, series, nstep, h)
    states, diverged = batch.rollout([model], [batch.initial_state(model, nu0=(0.5, 0.1, 0.0))], controls[None])
    assert diverged == [] and controls.shape == (nstep, 2)
    np.testing.assert_allclose(states[0, :, 1:4], run.eta[1:], rtol=0, atol=1e-9)


def test_models_without_params_are_rejected(compiled):
    model = compiled["yellowfish"].model
    with pytest.raises(TwinError):
        batch.rollout([model], np.zeros((1, batch.state_size(model))), np.zeros((1, 5, 2)))
    good = native.with_native_params(compiled["yellowfish"])
    with pytest.raises(TwinError):
        batch.rollout([good], np.zeros((1, batch.state_size(good))), np.zeros((1, 5, 3)))


def test_simulate_many_keeps_the_runs_that_did_not_diverge(compiled):
    """A run that blows up is reported by index and time; the others come back whole.
    Quadratic damping this stiff is stable at rest and explodes at 1 m/s (explicit damping
    force, 2 ms steps)."""
    yf = compiled["yellowfish"]
    stiff = CompiledVessel(replace(yf.vessel, damping=replace(yf.vessel.damping, Xuu=-1e5, Nrr=-1e5)),
                           yf.model, yf.geometry)
    idle = InputSeries(np.array([0.0]), np.array([[1500.0, 1500.0]]), "pwm")
    gentle = InputSeries(np.array([0.0, 1.0]), np.array([[1500.0, 1500.0], [1700.0, 1650.0]]), "pwm")
    runs = batch.simulate_many(stiff, [gentle, idle, gentle], [5.0, 5.0, 3.0], nu0=[None, (1.0, 0.0, 0.0), None],
                               start_s=[0.0, 10.0, 20.0], sample_dt_s=0.1)
    assert len(runs) == 3 and runs[1] is None
    [(index, t_s)] = runs.diverged
    assert index == 1 and 10.0 < t_s < 10.1  # on the run's own clock (start_s = 10 s)
    assert "run 1 at t = 10.02 s" in runs.describe_divergence()
    with pytest.raises(TwinError, match="diverged at t = 10.02 s"):  # alone, it fails at the same time
        simulate(stiff, idle, 5.0, nu0=(1.0, 0.0, 0.0), start_s=10.0)
    for run, start, duration in ((runs[0], 0.0, 5.0), (runs[2], 20.0, 3.0)):
        alone = simulate(stiff, gentle, duration, start_s=start)
        np.testing.assert_allclose(run.t, alone.t, atol=1e-9)
        np.testing.assert_allclose(run.eta, alone.eta, atol=1e-9)
        assert np.ptp(run.eta[:, 0]) > 0.01  # it did move
    assert batch.simulate_many(yf, [idle], [2.0]).diverged == []
