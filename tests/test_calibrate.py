"""Each log's own compass offset from its kinematics (fit/calibrate.py): GNSS track against the
logged heading, ahead and astern, with the sideslip of gentle turns told apart."""
import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin.engine.mjcf import compile_vessel
from twin.fit.calibrate import kinematic_calibration
from twin.geodesy import geodetic_from_ned
from twin.recording import Recording, Stream

DT = 0.1


def _log(legs, offset_deg: float, seed: int = 0) -> Recording:
    """A kinematic log: legs of (seconds, u m/s, r rad/s) from heading 50°, the boat's sway
    v = 0.2·u·r (a turn's sideslip), the compass reading offset_deg more than the true heading,
    2 cm of GNSS jitter."""
    rng = np.random.default_rng(seed)
    u = np.concatenate([np.full(int(s / DT), a) for s, a, _ in legs])
    r = np.concatenate([np.full(int(s / DT), b) for s, _, b in legs])
    v = 0.2 * u * r
    psi = np.radians(50.0) + np.cumsum(r) * DT
    n = np.cumsum(u * np.cos(psi) - v * np.sin(psi)) * DT + rng.normal(0, 0.02, len(u))
    e = np.cumsum(u * np.sin(psi) + v * np.cos(psi)) * DT + rng.normal(0, 0.02, len(u))
    t = np.arange(len(u)) * DT
    lat, lon = geodetic_from_ned(n, e, 63.4, 10.3)
    alt = np.zeros_like(lat)
    return Recording("log.csv", "csv", gnss=Stream(t, {"lat_deg": lat, "lon_deg": lon, "alt_m": alt}),
                     heading=Stream(t, {"psi_rad": psi + np.radians(offset_deg)}),
                     pwm=Stream(t, {"left_us": np.full(len(t), 1500.0), "right_us": np.full(len(t), 1500.0)}))


@pytest.fixture(scope="module")
def blueboat():
    return compile_vessel(vessel_mod.load("blueboat"))


def test_astern_running_and_gentle_turns_give_the_offset(blueboat):
    # astern on a straight line, then ahead weaving at ±0.25 rad/s: no stretch with |r| < 0.1 under way ahead
    log = _log([(15, -1.5, 0.0), (3, 0.0, 0.0), (8, 1.8, 0.25), (8, 1.8, -0.25), (8, 1.8, 0.25)], 7.0)
    cal = kinematic_calibration(log, blueboat)
    assert cal.heading_bias_deg == pytest.approx(7.0, abs=1.0)
    assert cal.sigma_deg < 2.0 and cal.seconds > 20


def test_no_straight_running_no_offset(blueboat):
    cal = kinematic_calibration(_log([(20, 0.1, 0.8)], 7.0), blueboat)  # a spin in place
    assert cal.heading_bias_deg is None and "straight running" in cal.note


def test_gnss_latency_reads_the_fixes_late_on_the_same_grid(blueboat):
    """A late receiver: the fix stamped t was taken at t − L. Read L later, the track is the
    true one again, and the grid (so every diagnosis window) stays the logged one."""
    from dataclasses import replace

    from twin.engine.mjcf import CompiledVessel
    from twin.fit.calibrate import prepare_for
    from twin.recording import Stream

    log = _log([(20, 1.5, 0.2)], 0.0)
    late = replace(log, gnss=Stream(log.gnss.t + 0.4, log.gnss.columns))  # stamped 0.4 s late
    v = blueboat.vessel
    fixed = replace(v, sensors=replace(v.sensors, gnss_latency_s=0.4))
    truth = prepare_for(log, blueboat)
    plain = prepare_for(late, blueboat)
    read_late = prepare_for(late, CompiledVessel(fixed, blueboat.model, blueboat.geometry))
    np.testing.assert_array_equal(read_late.t, plain.t)
    inner = slice(20, -20)  # away from the ends, where the late read runs out of fixes
    common = np.intersect1d(truth.t[inner], read_late.t[inner])
    at = lambda p, x: np.interp(common, p.t, x)  # noqa: E731
    err_plain = np.abs(at(plain, plain.v) - at(truth, truth.v)).max()
    err_read = np.abs(at(read_late, read_late.v) - at(truth, truth.v)).max()
    assert err_plain > 0.05 and err_read < 0.2 * err_plain
