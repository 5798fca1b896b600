"""The fast single-run loop gives the bits of the step-by-step reference loop (engine/sim_reference.py):
open-loop series and closed-loop controllers, every thruster effect, both backends, the
divergence message; its float arithmetic per tick equals the numpy maps; the vectorised CSV
writer writes the text of csv.writer cell by cell. Correctness only: speed is measured by
scripts/bench.py, never here."""
import csv
import io
from dataclasses import replace

import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin.drive import InputSeries, ZigZag, random_rc, spin, step, to_thruster_inputs, turn
from twin.engine.mjcf import CompiledVessel, compile_vessel
from twin.engine.sim import simulate
from twin.engine.sim_reference import simulate_reference
from twin.engine.tick import TickMap
from twin.errors import TwinError
from twin.physics.damping import Damping
from twin.physics.hydrodynamics import Terms
from twin.physics.thrusters import ThrusterModel
from twin.run import CSV_COLUMNS, Run

EFFECTS = dict(delay_s=0.13, decay_per_min=0.05, lag_s=0.2, advance_loss=1.0, gain_right=0.9)
_rng = np.random.default_rng(42)
_T = np.concatenate([[0.0], np.sort(_rng.uniform(0.01, 30.0, 25))])
PWM = InputSeries(_T, _rng.uniform(1050, 1950, (len(_T), 2)).round(1), "pwm")
THRUST = InputSeries(_T, _rng.uniform(-2.5, 2.5, (len(_T), 2)), "thrust")


class ThrustController:
    """Thrusts in N straight from the controller."""

    output = "thrust"

    def __call__(self, t, eta, nu):
        return 1.5 * np.cos(0.3 * t), 1.0 - 0.5 * np.sin(0.2 * t)


def odd_types(t, eta, nu):
    """Outputs the float path does not take: numpy float32, a list, ints, a 0-d array."""
    kind = int(round(t / 0.1)) % 4
    if kind == 0:
        return np.float32(0.4), np.float32(-0.3)
    if kind == 1:
        return [0.5, 0.2]
    if kind == 2:
        return 1, 0
    return np.array(0.3), 0.7


_compiled: dict = {}


def vessel(name: str = "yellowfish", **thrusters) -> CompiledVessel:
    key = (name, tuple(sorted(thrusters.items())))
    if key not in _compiled:
        v = vessel_mod.load(name)
        _compiled[key] = compile_vessel(replace(v, thrusters=replace(v.thrusters, **thrusters)) if thrusters else v)
    return _compiled[key]


# (name, vessel, drive factory (stateful controllers: a fresh one per run), duration s, simulate kwargs)
CASES = [
    ("zigzag", lambda: vessel(), ZigZag, 60.0, {}),
    ("random", lambda: vessel(), lambda: random_rc(3), 60.0, {}),
    ("thrust vessel zigzag", lambda: vessel("cybership1"), ZigZag, 30.0, {}),
    ("all effects, closed loop", lambda: vessel(**EFFECTS), ZigZag, 30.0, dict(start_s=30.0, sample_dt_s=0.2)),
    ("effects, fast autopilot", lambda: vessel(**EFFECTS), lambda: random_rc(1), 20.0,
     dict(start_s=5.0, control_dt_s=0.04)),
    ("delay over two ticks", lambda: vessel(delay_s=0.3), turn, 20.0, dict(control_dt_s=0.2, sample_dt_s=0.04)),
    ("lag", lambda: vessel(lag_s=0.5), lambda: step(surge=0.6, at_s=0.0), 10.0, {}),
    ("ramp, closed loop", lambda: vessel(ramp_s=2.0, delay_s=0.1, decay_per_min=0.1), ZigZag, 20.0,
     dict(start_s=3.0, sample_dt_s=0.04)),
    ("ramp and lag, pwm series", lambda: vessel(ramp_s=1.5, lag_s=0.3), lambda: PWM, 20.0, dict(sample_dt_s=0.02)),
    ("thrust controller", lambda: vessel(), ThrustController, 20.0, {}),
    ("odd output types", lambda: vessel(delay_s=0.1), lambda: odd_types, 10.0, {}),
    ("thrust off", lambda: vessel(decay_per_min=0.1), ZigZag, 10.0,
     dict(terms=Terms(thrust=False), nu0=(1.0, 0.0, 0.1))),
    ("python backend", lambda: vessel(), lambda: ZigZag(at_s=1.0), 4.0, dict(backend="python")),
    ("odd duration and periods", lambda: vessel(), spin, 10.05, dict(sample_dt_s=0.2, control_dt_s=0.06)),
    ("thrust vessel, decay and delay", lambda: vessel("cybership1", delay_s=0.05, decay_per_min=0.3),
     lambda: random_rc(7), 10.0, dict(control_dt_s=0.03, sample_dt_s=0.02)),
    ("pwm series", lambda: vessel(), lambda: PWM, 30.0,
     dict(start_s=12.3, nu0=(0.5, 0.1, 0.05), eta0=(1.0, -2.0, 0.7))),
    ("pwm series, all effects", lambda: vessel(**EFFECTS), lambda: PWM, 30.0, dict(start_s=12.3, sample_dt_s=0.02)),
    ("thrust series", lambda: vessel("cybership1"), lambda: THRUST, 30.0, dict(sample_dt_s=0.05)),
]


@pytest.mark.parametrize("name,compiled,drive,duration,kwargs", CASES, ids=[c[0] for c in CASES])
def test_fast_loop_gives_the_bits_of_the_reference_loop(name, compiled, drive, duration, kwargs):
    cv = compiled()
    fast = simulate(cv, drive(), duration, **kwargs)
    ref = simulate_reference(cv, drive(), duration, **kwargs)
    for field in ("t", "eta", "nu", "pwm_us", "thrust_n"):
        a, b = getattr(fast, field), getattr(ref, field)
        assert a.shape == b.shape and a.dtype == b.dtype, field
        assert np.array_equal(a, b, equal_nan=True), field
    assert {k: v for k, v in fast.meta.items() if k != "inputs"} == {k: v for k, v in ref.meta.items() if k != "inputs"}
    mine, theirs = fast.meta["inputs"], ref.meta["inputs"]
    assert mine.kind == theirs.kind
    assert np.array_equal(mine.t, theirs.t) and np.array_equal(mine.values, theirs.values)
    assert mine.values.dtype == theirs.values.dtype
    assert fast.to_csv_text() == ref.to_csv_text()


def _anti_damped(name: str = "yellowfish", **thrusters) -> CompiledVessel:
    """Positive (anti-)damping: the twin blows up within seconds (as in test_engine)."""
    cv = vessel(name, **thrusters)
    return CompiledVessel(replace(cv.vessel, damping=Damping(Xu=200.0, Yv=200.0, Nr=200.0)), cv.model, cv.geometry)


@pytest.mark.parametrize("drive", [ZigZag, lambda: PWM], ids=["closed loop", "open loop"])
def test_divergence_is_reported_as_the_reference_loop_reports_it(drive):
    cv = _anti_damped(delay_s=0.1)
    with pytest.raises(TwinError) as fast:
        simulate(cv, drive(), 60.0, start_s=100.0, sample_dt_s=0.2)
    with pytest.raises(TwinError) as ref:
        simulate_reference(cv, drive(), 60.0, start_s=100.0, sample_dt_s=0.2)
    assert "diverged at t = " in str(fast.value)
    assert str(fast.value) == str(ref.value)


@pytest.mark.parametrize("name", ["yellowfish", "blueboat", "cybership1"])
def test_tick_maps_equal_the_numpy_maps(name):
    thrusters = vessel_mod.load(name).thrusters
    _check_maps(thrusters)
    _check_maps(replace(thrusters, decay_per_min=0.37))


def _check_maps(thrusters: ThrusterModel) -> None:
    tick = TickMap.of(thrusters)
    rng = np.random.default_rng(0)
    levels = np.concatenate([rng.uniform(-1.6, 1.6, 4000), [0.0, -0.0, 1.0, -1.0, 0.5, -0.5, np.nan, np.inf]])
    surge, yaw = rng.permutation(levels), levels
    for s, y in zip(surge.tolist(), yaw.tolist()):
        kind, held = to_thruster_inputs(thrusters, s, y)
        mine_kind, mine = tick.held(None, (s, y))
        assert mine_kind == kind
        assert np.array_equal(np.array(mine), held, equal_nan=True)
        assert np.array_equal(np.signbit(mine), np.signbit(held))
        expected = thrusters.command(kind, held[None, :], [0.0])[0]
        assert np.array_equal(np.array(tick.raw_thrust(kind, mine)), expected, equal_nan=True)
    if thrusters.kind == "t200":  # every PWM near the dead zone's and the range's edges
        edges = [(x + thrusters.pwm_offset) * thrusters.pwm_scale_us
                 for x in (thrusters.deadzone_fwd, thrusters.deadzone_rev)]
        edges += [thrusters.pwm_min_us, thrusters.pwm_max_us]
        pwm = np.concatenate([np.linspace(900, 2100, 24001), np.array(edges)[:, None] + np.linspace(-1e-3, 1e-3, 41),
                              [np.nan, np.inf, -np.inf]], axis=None)
        raw = thrusters.thrust_from_pwm(np.column_stack([pwm, pwm[::-1]]))
        mine = np.array([tick.raw_thrust("pwm", pair) for pair in zip(pwm.tolist(), pwm[::-1].tolist())])
        assert np.array_equal(mine, raw, equal_nan=True)
    times = np.concatenate([np.linspace(-10.0, 400.0, 4001), [60.0 / max(thrusters.decay_per_min, 1e-9)]])
    assert np.array_equal([tick.decay(t) for t in times.tolist()], thrusters.decay_factor(times))


def _csv_cell_by_cell(run: Run) -> str:
    """The writer the vectorised one replaced: csv.writer, '{:.9g}' per cell, empty if not finite."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    cols = run.columns()
    for i in range(len(run.t)):
        w.writerow(["" if not np.isfinite(cols[c][i]) else f"{cols[c][i]:.9g}" for c in CSV_COLUMNS])
    return buf.getvalue()


def test_csv_text_equals_the_cell_by_cell_writer():
    run = simulate(vessel("cybership1"), THRUST, 20.0)  # driven by thrust: the PWM cells are empty
    assert np.isnan(run.pwm_us).all()
    special = [np.nan, np.inf, -np.inf, 0.0, -0.0, 5e-324, 1.7976931348623157e308, 999999999.5, 9.9999999995e-5,
               1e16, 123456789012.0, -1 / 3]
    run.eta[: len(special), 0] = special
    run.nu[-len(special):, 2] = special
    assert run.to_csv_text() == _csv_cell_by_cell(run)
    ints = Run(np.arange(5), np.ones((5, 3), np.float32) / 3, np.zeros((5, 3), int), np.full((5, 2), 1500),
               np.full((5, 2), np.nan))
    assert ints.to_csv_text() == _csv_cell_by_cell(ints)
    empty = Run(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2)))
    assert empty.to_csv_text() == _csv_cell_by_cell(empty) == ",".join(CSV_COLUMNS) + "\n"
