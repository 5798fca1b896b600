"""The heading's delay against the gyro, from the two streams alone (twin.prepare.timing)."""
import numpy as np
import pytest

from twin.prepare.timing import GyroLag, heading_lag_behind_gyro
from twin.recording import Recording, Stream


def _log(heading_delay_s: float = 0.0, tau_s: float = 0.0, turn_rad_s: float = 0.4, seed: int = 0) -> Recording:
    """A boat weaving (yaw rate a sum of slow sines), the gyro on time with 0.005 rad/s of noise and a
    0.01 rad/s bias, the heading at 20 Hz with 0.3° of noise, stamped heading_delay_s late and/or passed
    through a first-order filter of τ."""
    rng = np.random.default_rng(seed)
    dt = 0.01
    t = np.arange(0.0, 300.0, dt)
    r = turn_rad_s * (np.sin(2 * np.pi * t / 17.0) + 0.5 * np.sin(2 * np.pi * t / 6.3 + 1.0))
    psi = np.cumsum(r) * dt
    if tau_s:
        a = dt / (tau_s + dt)
        out = np.empty_like(psi)
        out[0] = psi[0]
        for k in range(1, len(psi)):
            out[k] = out[k - 1] + a * (psi[k] - out[k - 1])
        psi = out
    th = t[::5]
    psi_logged = np.interp(th - heading_delay_s, t, psi) + np.radians(0.3) * rng.standard_normal(len(th))
    tg = t[::2]
    gyro = np.interp(tg, t, r) + 0.01 + 0.005 * rng.standard_normal(len(tg))
    return Recording("weave.csv", "csv", heading=Stream(th, {"psi_rad": np.mod(psi_logged, 2 * np.pi)}),
                     imu=Stream(tg, {"yaw_rate_rads": gyro}))


@pytest.mark.parametrize("delay", [0.0, 0.25, 0.6, -0.2])
def test_a_pure_delay_is_read_to_the_scan_step(delay):
    got = heading_lag_behind_gyro(_log(heading_delay_s=delay))
    assert got.lag_s == pytest.approx(delay, abs=0.02) and got.fit > 0.99


def test_a_first_order_filter_reads_close_to_its_time_constant():
    """Slow weaving (periods 6-17 s): a filter of τ 0.4 s delays it by a little under τ."""
    got = heading_lag_behind_gyro(_log(tau_s=0.4))
    assert 0.33 <= got.lag_s <= 0.41


def test_without_a_gyro_or_turning_nothing_is_told():
    rec = _log()
    assert heading_lag_behind_gyro(Recording("x.csv", "csv", heading=rec.heading)).lag_s is None
    straight = heading_lag_behind_gyro(_log(turn_rad_s=0.01))
    assert straight.lag_s is None and "turning" in straight.note


def test_the_diagnosis_notes_each_logs_heading_against_its_gyro():
    from twin.diagnose.doctor import _gyro_timing

    late, plain = _log(heading_delay_s=0.25), _log(turn_rad_s=0.01)
    notes = _gyro_timing([late, Recording("still.csv", "csv", heading=plain.heading, imu=plain.imu)])
    assert len(notes) == 2 and notes[0].startswith("weave.csv: heading against the gyro: +")
    assert float(notes[0].split(": +")[1].split(" s late")[0]) == pytest.approx(0.25, abs=0.02)
    assert "`heading_latency=0.2" in notes[0]  # told: well beyond its σ
    # turning too slowly for 10-s pieces: read on a ship's 60-s pieces, as `twin info` reads it, and on time
    assert notes[1].startswith("still.csv: heading against the gyro:") and notes[1].endswith("not told from on time "
                                                                                               "(within 3σ)")


def test_a_gyro_of_the_other_sign_is_not_read_as_a_lag():
    rec = _log(heading_delay_s=0.3)
    port_positive = Stream(rec.imu.t, {"yaw_rate_rads": -rec.imu["yaw_rate_rads"]})
    flipped = Recording("x.csv", "csv", heading=rec.heading, imu=port_positive)
    got = heading_lag_behind_gyro(flipped)
    assert got.lag_s is None and "explains only" in got.note
    gain = float(got.note.split("the gyro turns ")[1].split(" times")[0])
    assert gain == pytest.approx(-1.0, abs=0.05) and "rad/s, positive turning to starboard" in got.note


def test_a_slow_turner_with_a_good_gyro_is_not_told_to_check_its_units():
    # a ship model turning at about 3°/s under 3° of heading noise: within 10-s pieces the gyro explains
    # little, over the whole log it turns as far as the heading: units and sign are not the cause
    rec = _log(turn_rad_s=0.06, seed=3)
    noisy = Stream(rec.heading.t, {"psi_rad": np.mod(np.unwrap(rec.heading["psi_rad"]) + np.radians(3.0) *
                                                  np.random.default_rng(4).standard_normal(len(rec.heading)),
                                                  2 * np.pi)})
    got = heading_lag_behind_gyro(Recording("ship.csv", "csv", heading=noisy, imu=rec.imu))
    assert got.lag_s is None and got.fit < 0.9
    assert "units and sign right" in got.note and "rad/s, positive" not in got.note


def test_the_search_fits_a_heading_or_a_fix_late_only_and_a_pwm_clock_both_ways():
    """A filter or a receiver delays a sample: the diagnosis's candidates for a heading's and a fix's
    latency start at zero and never scan or fit below it; two clocks can differ either way."""
    import twin.vessel as vessel_mod
    from twin.effects import EFFECTS

    prior = vessel_mod.load("blueboat")
    for name, lowest in (("heading_latency", 0.0), ("gnss_latency", 0.0), ("clock_offset", -0.9)):
        cand = EFFECTS[name].fit(prior, ["a.csv"])
        (q,) = cand.params
        assert q.lo == lowest if lowest == 0.0 else q.lo < lowest, name
        assert min(v[0] for v in cand.scan) == pytest.approx(lowest, abs=0.1), name


def test_a_lag_within_three_sigma_of_zero_is_not_said_to_describe_the_heading():
    vague = GyroLag(0.79, 0.95, 120.0, sigma_s=0.82).text()
    assert "+0.79 s late ± 0.82 s" in vague and "not told from on time" in vague and "heading_latency=" not in vague
    early = GyroLag(-0.20, 0.97, 300.0, sigma_s=0.05).text()
    assert "leads its gyro" in early and "heading_latency=" not in early
    late = GyroLag(0.40, 0.97, 300.0, sigma_s=0.05).text()
    assert "`heading_latency=0.40` describes it" in late


def test_the_diagnosis_reads_a_boats_late_heading_as_twin_info_does():
    """A boat's 160-s log with a heading 0.3 s late: too short for three of a ship's 60-s pieces
    (no spread, so the diagnosis could not tell it), told from 10-s pieces as `twin info` tells it."""
    from twin.fit.kinematic import _gyro_heading
    from twin.recording import within
    from twin.vessel import load

    rec = within(_log(heading_delay_s=0.3), 0.0, 160.0, "weave.csv")
    found = _gyro_heading([rec], load("blueboat"), floor=0.15)
    assert found.told and found.values["heading_latency_s"] == pytest.approx(0.3, abs=0.02), found.why
    on_time = _gyro_heading([within(_log(), 0.0, 160.0, "weave.csv")], load("blueboat"), floor=0.15)
    assert not on_time.told and on_time.absent, on_time.why
