"""Each log's own compass offset from its kinematics (fit/calibrate.py): GNSS track against the
logged heading, ahead and astern, with the sideslip of gentle turns told apart."""
import numpy as np
import pytest

import twin.vessel as vessel_mod
from twin.drive import InputSeries
from twin.engine.mjcf import compile_vessel
from twin.fit.calibrate import kinematic_calibration
from twin.geodesy import geodetic_from_ned
from twin.recording import Recording, Stream
from twin.simulation import simulate_run

DT = 0.1


def _log(legs, offset_deg: float, seed: int = 0, drift=(0.0, 0.0), name: str = "log.csv") -> Recording:
    """A kinematic log: legs of (seconds, u m/s, r rad/s) from heading 50°, the boat's sway
    v = 0.2·u·r (a turn's sideslip), the compass reading offset_deg more than the true heading,
    2 cm of GNSS jitter; the water drifting at drift (NED m/s); the thrusters at 1800 µs (1200 astern)
    where the boat makes way, at neutral where it lies still (u = 0: drifting with the water)."""
    rng = np.random.default_rng(seed)
    u = np.concatenate([np.full(int(s / DT), a) for s, a, _ in legs])
    r = np.concatenate([np.full(int(s / DT), b) for s, _, b in legs])
    v = 0.2 * u * r
    psi = np.radians(50.0) + np.cumsum(r) * DT
    n = np.cumsum(u * np.cos(psi) - v * np.sin(psi) + drift[0]) * DT + rng.normal(0, 0.02, len(u))
    e = np.cumsum(u * np.sin(psi) + v * np.cos(psi) + drift[1]) * DT + rng.normal(0, 0.02, len(u))
    t = np.arange(len(u)) * DT
    lat, lon = geodetic_from_ned(n, e, 63.4, 10.3)
    alt = np.zeros_like(lat)
    return Recording(name, "csv", gnss=Stream(t, {"lat_deg": lat, "lon_deg": lon, "alt_m": alt}),
                     heading=Stream(t, {"psi_rad": psi + np.radians(offset_deg)}),
                     pwm=Stream(t, {"left_us": 1500.0 + 300.0 * np.sign(u), "right_us": 1500.0 + 300.0 * np.sign(u)}))


@pytest.fixture(scope="module")
def blueboat():
    return compile_vessel(vessel_mod.load("blueboat"))


def test_astern_running_and_gentle_turns_give_the_offset(blueboat):
    # astern on a straight line, then ahead weaving at ±0.25 rad/s: a turn rate of 0.17 per ship length
    # (1.2 m at 1.8 m/s), where the BlueBoat's own drift angle stays under 0.03 rad; its sideslip
    # (here 0.2·u·r) is fitted beside the offset
    log = _log([(15, -1.5, 0.0), (3, 0.0, 0.0), (8, 1.8, 0.25), (8, 1.8, -0.25), (8, 1.8, 0.25)], 7.0)
    cal = kinematic_calibration(log, blueboat)
    assert cal.heading_bias_deg == pytest.approx(7.0, abs=1.0)
    assert cal.sigma_deg < 2.0 and cal.seconds > 20


def test_a_ships_turns_and_zigzags_are_not_read_as_a_compass_offset():
    """The Esso Osaka's own noise-free runs at 17 rps, heading exact: a turning circle (its drift
    angle steady) and zig-zags of ±35° every 10 s (the yaw rate passing zero while the drift angle is
    largest) give no offset; a dimensional yaw-rate bound (0.35 rad/s) took both for straight running
    and read the zig-zags' drift as an offset of 7.8°."""
    from dataclasses import replace

    shipped = vessel_mod.load("esso_osaka")  # its bound, 10 rps, is the shared tests' fastest
    esso = replace(shipped, thrusters=replace(shipped.thrusters, rps_max=20.0))
    t = np.arange(0.0, 120.0, 0.1)
    rps = np.minimum(17.0 * t / 5.0, 17.0)
    zigzag = np.where((t > 40) & (t < 80), 35.0 * np.sign(np.sin(2 * np.pi * t / 20) + 1e-9), 0.0)
    for rudder_deg in (np.where(t > 40, 20.0, 0.0), zigzag):
        inputs = InputSeries(t, np.column_stack([rps, np.radians(rudder_deg)]), "propeller_rudder")
        run = simulate_run(esso, inputs=inputs, duration_s=120.0).run
        lat, lon = geodetic_from_ned(run.eta[:, 0], run.eta[:, 1], 34.7, 135.5)
        log = Recording("ship.csv", "csv", gnss=Stream(run.t, {"lat_deg": lat, "lon_deg": lon, "alt_m": 0 * lat}),
                        heading=Stream(run.t, {"psi_rad": run.eta[:, 2]}),
                        prop_rudder=Stream(t, {"n_rps": rps, "delta_rad": np.radians(rudder_deg)}))
        cal = kinematic_calibration(log, compile_vessel(esso))
        assert cal.heading_bias_deg is None, cal.text()


def test_a_log_whose_legs_point_one_way_is_read_with_the_other_logs_drifts(blueboat):
    """A 0.25 m/s current across the track: three logs with legs on three headings fit it beside their
    offsets; a fourth, straight one way only, would take the current's crab for a compass offset
    (about 11° at 1.2 m/s), and read with the others' drifts gets its own offset back."""
    from twin.fit.calibrate import kinematic_calibrations

    drift = (0.06, -0.24)
    turning = [(15, 1.2, 0.0), (1.5, 0.0, 1.047), (15, 1.2, 0.0), (1.5, 0.0, 1.047), (15, 1.2, 0.0)]
    logs = [_log(turning, off, seed=i, drift=drift, name=f"log{i}.csv") for i, off in enumerate((3.0, -2.0, 4.0))]
    one_way = _log([(20, 1.2, 0.0), (3, 0.0, 0.0), (20, 1.2, 0.0)], -1.9, seed=5, drift=drift, name="log3.csv")
    alone = kinematic_calibration(one_way, blueboat)
    assert alone.drift_ned_m_s is None and abs(alone.heading_bias_deg - (-1.9)) > 5.0
    cals = kinematic_calibrations(logs + [one_way], blueboat)
    assert [c.heading_bias_deg for c in cals[:3]] == pytest.approx([3.0, -2.0, 4.0], abs=0.7)
    assert cals[3].heading_bias_deg == pytest.approx(-1.9, abs=0.7) and cals[3].drift_from_logs == 3
    assert cals[3].drift_ned_m_s == pytest.approx(drift, abs=0.03) and "3 other logs'" in cals[3].text()
    assert kinematic_calibrations(logs[:1] + [one_way], blueboat)[1] == alone  # one other drift: nothing borrowed


def test_a_log_under_its_own_wind_is_not_read_with_the_other_logs_drifts(blueboat):
    """Three logs drift with (0.06, −0.24) m/s and fit it on their legs; a fourth, straight one way and
    with no compass offset, drifts under a wind of its own outing, (0.30, 0.20) m/s: read with the
    others' drifts alone it takes the difference's crab for an offset of about −3.4°. Its own drift at
    rest (a minute idle, the boat moving with its water) reads another offset; the spread keeps it
    from being applied. Where the water is shared its drift at rest agrees and the offset is read."""
    from twin.fit.calibrate import REST_SPEED_M_S, kinematic_calibrations, prepare_for, rest_drift, settle_s

    turning = [(15, 1.2, 0.0), (1.5, 0.0, 1.047), (15, 1.2, 0.0), (1.5, 0.0, 1.047), (15, 1.2, 0.0)]
    logs = [_log(turning, off, seed=i, drift=(0.06, -0.24), name=f"log{i}.csv")
            for i, off in enumerate((3.0, -2.0, 4.0))]
    legs = [(20, 1.2, 0.0), (120, 0.0, 0.0), (20, 1.2, 0.0)]  # idle long enough to coast to rest (settle_s)
    windy = _log(legs, 0.0, seed=5, drift=(0.30, 0.20), name="log3.csv")
    assert rest_drift(prepare_for(windy, blueboat), settle_s(blueboat)) == pytest.approx((0.30, 0.20), abs=0.03)
    cal = kinematic_calibrations(logs + [windy], blueboat)[3]
    assert cal.heading_bias_deg is None and cal.drift_from_logs == 3 and "its own at rest" in cal.note
    import re
    lowest, highest = map(float, re.search(r"offsets ([-+][\d.]+)° to ([-+][\d.]+)°", cal.note).groups())
    assert lowest == pytest.approx(-3.4, abs=0.5) and highest == pytest.approx(0.0, abs=0.3)  # borrowed, at rest
    shared = _log(legs, -4.0, seed=6, drift=(0.06, -0.24), name="log4.csv")
    cal = kinematic_calibrations(logs + [shared], blueboat)[3]
    assert cal.heading_bias_deg == pytest.approx(-4.0, abs=0.7) and "its own at rest" in cal.note
    # the settling time is the coast-down of the surge row from 1 m/s to REST_SPEED_M_S (closed form)
    hydro = blueboat.hydro()
    u, t, dt = 1.0, 0.0, 1e-3
    while u > REST_SPEED_M_S:
        u += dt * (hydro.damping.Xu * u + hydro.damping.Xuu * u * abs(u)) / hydro.M[0, 0]
        t += dt
    assert settle_s(blueboat) == pytest.approx(t, rel=1e-3)


def test_heading_latency_reads_the_heading_late_on_the_same_grid(blueboat):
    """An AHRS stamping its heading 0.4 s late: in every turn the heading lags the track, so the measured
    sway carries +u·r·L. Read L later, the sway is the true one again; the grid stays the logged one."""
    from dataclasses import replace

    from twin.engine.mjcf import CompiledVessel
    from twin.fit.calibrate import prepare_for
    from twin.recording import Stream

    log = _log([(20, 1.5, 0.2)], 0.0)
    late = replace(log, heading=Stream(log.heading.t + 0.4, log.heading.columns))
    v = blueboat.vessel
    fixed = replace(v, sensors=replace(v.sensors, heading_latency_s=0.4))
    truth, plain = prepare_for(log, blueboat), prepare_for(late, blueboat)
    read_late = prepare_for(late, CompiledVessel(fixed, blueboat.model, blueboat.geometry))
    np.testing.assert_array_equal(read_late.t, plain.t)
    inner = slice(20, -20)
    common = np.intersect1d(truth.t[inner], read_late.t[inner])
    at = lambda p, x: np.interp(common, p.t, x)  # noqa: E731
    err_plain = np.abs(at(plain, plain.v) - at(truth, truth.v)).max()
    err_read = np.abs(at(read_late, read_late.v) - at(truth, truth.v)).max()
    assert err_plain > 0.05 and err_read < 0.2 * err_plain
    assert np.abs(at(read_late, read_late.r) - at(truth, truth.r)).max() < 0.01


def test_a_latency_never_reads_across_a_dropout(blueboat):
    """Read early (a negative latency) just after a GNSS dropout, the fix before the gap would describe
    the segment's first grid times, and the velocity a derivative across the gap (the boat slowed from
    1.5 to 0.5 m/s inside it: 0.37 m/s off before the fix). Held at the segment's edge instead, the
    speed after the gap stays the boat's, whatever the latency."""
    from dataclasses import replace

    from twin.engine.mjcf import CompiledVessel
    from twin.fit.calibrate import prepare_for
    from twin.recording import Stream

    log = _log([(17, 1.5, 0.0), (23, 0.5, 0.0)], 0.0)
    g = log.gnss
    keep = (g.t < 15.0) | (g.t > 20.0)  # a 5-s dropout
    gapped = replace(log, gnss=Stream(g.t[keep], {k: c[keep] for k, c in g.columns.items()}))
    v = blueboat.vessel
    for latency in (-0.43, 0.43):
        early = CompiledVessel(replace(v, sensors=replace(v.sensors, gnss_latency_s=latency)), blueboat.model,
                               blueboat.geometry)
        p = prepare_for(gapped, early)
        assert len(p.segments) == 2
        assert np.abs(p.u - 0.5)[p.t > 20.0].max() < 0.1 and np.abs(p.v).max() < 0.1


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


def _throttle_log(b_deg: float, c_deg: float, seed: int) -> Recording:
    """Straight legs of 20 s at 0.6-2.0 m/s on headings a turn of 3 s apart, the throttle growing with the
    speed (τ = u / 2.2), the water drifting (0.15, −0.1) m/s, the compass reading 3° plus τ·(B sin ψ + C cos ψ)."""
    rng = np.random.default_rng(seed)
    legs = [(20.0, 0.6 + 0.35 * (k % 5), 0.0) if k % 2 == 0 else (3.0, 1.0, 0.6) for k in range(36)]
    u = np.concatenate([np.full(int(s / DT), a) for s, a, _ in legs])
    r = np.concatenate([np.full(int(s / DT), b) for s, _, b in legs])
    psi = np.cumsum(r) * DT
    n = np.cumsum(u * np.cos(psi) + 0.15) * DT + rng.normal(0, 0.02, len(u))
    e = np.cumsum(u * np.sin(psi) - 0.10) * DT + rng.normal(0, 0.02, len(u))
    t = np.arange(len(u)) * DT
    lat, lon = geodetic_from_ned(n, e, 63.4, 10.3)
    tau = u / 2.2
    error = np.radians(3.0 + tau * (b_deg * np.sin(psi) + c_deg * np.cos(psi)))
    pwm = 1500.0 + 400.0 * tau
    return Recording("t.csv", "csv", gnss=Stream(t, {"lat_deg": lat, "lon_deg": lon, "alt_m": np.zeros_like(lat)}),
                     heading=Stream(t, {"psi_rad": psi + error}), pwm=Stream(t, {"left_us": pwm, "right_us": pwm}))


def test_a_compass_error_that_follows_the_throttle_is_told_from_a_drift(blueboat):
    """A one-cycle error at one speed is a drift; with the throttle growing with the speed the two part:
    the test recovers B, C beside the log's own offset and drift, and a compass without it is not flagged."""
    from twin.fit.calibrate import prepare_for, rate_windows, throttle_dependence

    vessel = blueboat.vessel
    got = throttle_dependence([prepare_for(_throttle_log(8.0, -5.0, 1), blueboat, **rate_windows(vessel))], vessel)
    assert got.shown and got.b_deg == pytest.approx(8.0, abs=1.0) and got.c_deg == pytest.approx(-5.0, abs=1.0)
    null = throttle_dependence([prepare_for(_throttle_log(0.0, 0.0, 2), blueboat, **rate_windows(vessel))], vessel)
    assert not null.shown and abs(null.b_deg) < 1.0 and abs(null.c_deg) < 1.0


def test_a_log_without_thruster_outputs_tells_no_throttle_dependence(blueboat):
    """A log whose throttle is not logged (no PWM: the prepared inputs are NaN) has pieces of straight
    running but no throttle to fit: no answer, not a least-squares failure on NaN."""
    from dataclasses import replace

    from twin.fit.calibrate import prepare_for, rate_windows, throttle_dependence
    from twin.recording import Stream

    vessel = blueboat.vessel
    log = replace(_throttle_log(8.0, -5.0, 1), pwm=Stream.empty("left_us", "right_us"))
    assert throttle_dependence([prepare_for(log, blueboat, **rate_windows(vessel))], vessel) is None


def test_a_recording_is_prepared_again_for_a_pwm_clock_its_compass_error_reads_the_throttle_on(blueboat):
    """Where the compass follows the motors' throttle, preparing a log reads the PWM at each heading
    sample on the PWM log's clock: a vessel with another clock offset sees another heading, and the
    diagnosis's measurements (fit.objective.Measurements) must be prepared again for it."""
    from dataclasses import replace

    from twin.fit.calibrate import prepare_for, rate_windows
    from twin.fit.objective import Measurements

    vessel = replace(blueboat.vessel, sensors=replace(blueboat.vessel.sensors, compass_motor_deg=(20.0, -10.0)))
    rec = _throttle_log(0.0, 0.0, 1)
    t = rec.pwm.t
    pwm = 1500.0 + 400.0 * (np.sin(2 * np.pi * t / 4.0) > 0)  # the throttle switches every 2 s
    rec = replace(rec, pwm=Stream(t, {"left_us": pwm, "right_us": pwm}))
    kw = rate_windows(vessel)
    data = Measurements([prepare_for(rec, compile_vessel(vessel), **kw)], [rec], compile_vessel(vessel), kw)
    late = replace(vessel, sensors=replace(vessel.sensors, pwm_clock_offset_s=1.0))
    got, fresh = data.for_vessel(late)[0], prepare_for(rec, compile_vessel(late), **kw)
    assert np.degrees(np.nanmax(np.abs(got.psi - data.preps[0].psi))) > 5.0  # the clock moves the heading
    np.testing.assert_array_equal(got.psi, fresh.psi)
