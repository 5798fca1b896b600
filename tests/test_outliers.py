"""GNSS fixes off their track and heading spikes: found where injected, never on hard manoeuvres,
left out of preparation and counted where the user sees them."""
from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from twin.engine.mjcf import compile_vessel
from twin.fit.calibrate import prepare_for
from twin.prepare import prepare
from twin.prepare.outliers import FLOOR_GNSS_M, describe, gnss_outliers, heading_spikes, held_fixes
from twin.prepare.prepared import local_ned, outlier_counts as counted
from twin.recording import Recording, Stream
from twin.vessel import load

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"


def manoeuvring_track(duration_s: float = 300.0, rate_hz: float = 5.0):
    """A boat at up to 3 m/s, turning and spinning at up to 1 rad/s, its yaw rate switched at
    2 rad/s² and its speed at 1.5 m/s² (what a 15-kg ASV's thrusters can do): (t, north, east, psi)
    of its GNSS antenna and heading with 2 cm and 0.3° noise (seeded)."""
    rng = np.random.default_rng(7)
    dt = 1.0 / rate_hz
    t = np.arange(0.0, duration_s, dt)
    r_target = np.where(t % 60 < 20, 0.4, np.where(t % 60 < 35, -1.0, np.where(t % 60 < 45, 1.0, 0.0)))
    u_target = np.where(t % 50 < 25, 3.0, 0.5)
    r, u = np.zeros(len(t)), np.zeros(len(t))
    for k in range(1, len(t)):
        r[k] = r[k - 1] + np.clip(r_target[k] - r[k - 1], -2.0 * dt, 2.0 * dt)
        u[k] = u[k - 1] + np.clip(u_target[k] - u[k - 1], -1.5 * dt, 1.5 * dt)
    psi = np.cumsum(r) * dt
    north = np.cumsum(u * np.cos(psi)) * dt + rng.normal(0, 0.02, len(t))
    east = np.cumsum(u * np.sin(psi)) * dt + rng.normal(0, 0.02, len(t))
    return t, north, east, psi + rng.normal(0, math.radians(0.3), len(t))


def test_a_clean_track_has_no_outliers_even_in_spins_and_fast_turns():
    t, north, east, psi = manoeuvring_track()
    assert gnss_outliers(north, east, t).sum() == 0
    assert heading_spikes(psi, t).sum() == 0


def test_injected_fixes_and_spikes_are_found_and_nothing_else():
    t, north, east, psi = manoeuvring_track()
    rng = np.random.default_rng(3)
    bad = rng.choice(np.arange(3, len(t) - 3), size=45, replace=False)  # 3 %, some side by side
    bad = np.unique(np.r_[bad, bad[:5] + 1])
    angle = rng.uniform(0, 2 * np.pi, len(bad))
    size = rng.uniform(1.0, 3.0, len(bad))
    n2, e2 = north.copy(), east.copy()
    n2[bad] += size * np.cos(angle)
    e2[bad] += size * np.sin(angle)
    found = gnss_outliers(n2, e2, t)
    assert set(np.flatnonzero(found)) == set(bad.tolist())
    spikes = rng.choice(np.arange(3, len(t) - 3), size=15, replace=False)
    p2 = psi.copy()
    p2[spikes] += np.radians(rng.uniform(8, 40, len(spikes))) * rng.choice([-1, 1], len(spikes))
    assert set(np.flatnonzero(heading_spikes(p2, t))) == set(spikes.tolist())


def test_a_step_that_stays_is_not_a_spike():
    """A heading that settles after start-up (the first sample far off, then steady) is no outlier."""
    t = np.arange(0.0, 10.0, 0.1)
    psi = np.zeros(len(t))
    psi[0] = np.radians(120.0)
    assert heading_spikes(psi, t).sum() == 0


def test_repeated_fixes_share_the_verdict_and_count_once():
    t, north, east, _ = manoeuvring_track(60.0, 5.0)
    north[100] += 2.0
    t10 = np.repeat(t, 2) + np.tile([0.0, 0.1], len(t))  # a 10 Hz logger repeating each 5 Hz fix
    mask = gnss_outliers(np.repeat(north, 2), np.repeat(east, 2), t10)
    assert np.flatnonzero(mask).tolist() == [200, 201]


def _stalled(x: np.ndarray, start: int, stop: int) -> np.ndarray:
    """x as a logger that stalls from `start` to `stop` logs it: the record before repeated."""
    out = x.copy()
    out[start:stop] = x[start - 1]
    return out


def test_a_partial_record_after_a_logger_stall_is_left_out():
    """A logger stalls for 2.5 s (its last record repeated), then logs a partial record 0.6 m short of
    the track before the fixes catch up (as the Esso Osaka's turn_14-Oct-2020_14_08_51 at 210.1 s):
    no chord across the stall is short enough to judge it, the next two fixes are. A stall whose
    first fresh record is on the track leaves nothing out."""
    t, north, east, _ = manoeuvring_track(60.0, 10.0)
    n2, e2 = _stalled(north, 150, 175), _stalled(east, 150, 175)  # at 3 m/s
    assert gnss_outliers(n2, e2, t).sum() == 0
    step = np.hypot(north[175] - north[149], east[175] - east[149])
    assert step > 5.0  # the boat moved on during the stall
    short = 0.6 / step  # the partial record: 0.6 m back along the chord from the held fix
    n2[175] -= short * (north[175] - north[149])
    e2[175] -= short * (east[175] - east[149])
    assert np.flatnonzero(gnss_outliers(n2, e2, t)).tolist() == [175]


def _recording(t, north, east, psi) -> Recording:
    rec = Recording(source="synthetic.csv", kind="csv")
    rec.gnss = Stream(t, {"north_m": north, "east_m": east})
    rec.heading = Stream(t, {"psi_rad": psi})
    rec.pwm = Stream(t, {"left_us": np.full(len(t), 1600.0), "right_us": np.full(len(t), 1600.0)})
    return rec


def test_preparation_leaves_outliers_out_and_counts_them():
    t, north, east, psi = manoeuvring_track(120.0, 5.0)
    clean = prepare(_recording(t, north, east, psi))
    n2 = north.copy()
    n2[[50, 200, 400]] += 2.5
    p2 = psi.copy()
    p2[300] += np.radians(30.0)
    rec = _recording(t, n2, east, p2)
    faulty = prepare(rec)
    dropped = dict(faulty.dropped)
    assert dropped["GNSS fixes off their neighbours' track (outliers)"] == 3
    assert dropped["heading spikes (outliers)"] == 1
    # without them the velocities are those of the clean track; with them a 2.5 m jump would make
    # the Savitzky-Golay velocity several m/s wrong around each
    assert np.nanmax(np.abs(faulty.u - clean.u)) < 0.3
    assert np.nanmax(np.abs(faulty.r - clean.r)) < 0.05
    assert counted(rec) == {"gnss": 3, "gnss_held": 0, "heading": 1}
    assert any(f"{FLOOR_GNSS_M:g} m" in line and line.endswith(": 3") for line in describe(counted(rec)))


def test_shared_real_logs_have_no_outliers():
    """The real BlueBoat and Esso Osaka logs: nothing is left out (the rule changes nothing there)."""
    if not SHARED.is_dir():
        pytest.skip("../shared/data not present")
    from twin.formats import read_recording

    paths = sorted((SHARED / "blueboat").glob("*.csv"))[:4] + sorted((SHARED / "esso").glob("turn_14-Sep*.csv"))[:2]
    for path in paths:
        assert counted(read_recording(path)) == {"gnss": 0, "gnss_held": 0, "heading": 0}, path.name


def test_after_a_dropout_a_good_fix_beside_an_outlier_stays():
    """A dropout of 10 s, its first fix on the track and the next one thrown 1.3 m (world seed 51's
    measurement faults): the thrown fix is left out and the good one stays (judged by one-sided
    chords only after the centred ones have left out what they find, its chord no longer runs
    through the outlier)."""
    t, north, east, _ = manoeuvring_track(120.0, 5.0)
    keep = (t < 50.0) | (t >= 60.0)
    t, north, east = t[keep], north[keep], east[keep]
    after = int(np.searchsorted(t, 60.0))
    north[after + 1] += 1.0
    east[after + 1] -= 0.8
    assert np.flatnonzero(gnss_outliers(north, east, t)).tolist() == [after + 1]


def test_the_esso_osaka_partial_record_after_a_stall_is_found():
    """turn_14-Oct-2020_14_08_51: the logger stalls for 2.7 s before 210.1 s and then logs a fix 0.56 m
    short of the track; that fix alone is left out (the one fix the one-sided chords add on every
    shared log)."""
    path = SHARED / "esso" / "turn_14-Oct-2020_14_08_51.csv"
    if not path.is_file():
        pytest.skip("../shared/data not present")
    from twin.formats import read_recording

    rec = read_recording(path)
    assert counted(rec)["gnss"] == 1
    n, e, _ = local_ned(rec.gnss)
    flagged = rec.gnss.t[gnss_outliers(n, e, rec.gnss.t)]
    assert flagged.tolist() == pytest.approx([210.1], abs=0.05)


def _straight(speed_m_s: float, duration_s: float = 20.0, rate_hz: float = 10.0, seed: int = 5):
    """A track due north at `speed_m_s` (a function of t, or a number) with 1 mm of noise (seeded):
    (t, north, east)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    speed = speed_m_s(t) if callable(speed_m_s) else np.full(len(t), float(speed_m_s))
    north = np.concatenate([[0.0], np.cumsum(speed[1:] * np.diff(t))]) + rng.normal(0, 0.001, len(t))
    return t, north, rng.normal(0, 0.001, len(t))


def test_a_fix_held_while_the_vessel_moved_on_is_taken_across():
    """The receiver holds its fix for 1.9 s with a few mm of dither while the ship runs on at 0.37 m/s
    (the Esso Osaka's turn_14-Oct-2020_15_21_57 at 79.4 s): the stand's fixes after its first are
    held, and preparation's velocity across them is the ship's, not a stop and a 0.74-m jump."""
    t, north, east = _straight(0.37)
    stand = slice(80, 99)  # 8.0 s .. 9.8 s
    n2 = north.copy()
    n2[stand] = north[80] + np.random.default_rng(1).normal(0, 0.002, 19)
    held = held_fixes(n2, east, t)
    assert np.flatnonzero(held).tolist() == list(range(81, 99))
    psi = np.zeros(len(t))
    u = prepare(_recording(t, n2, east, psi)).u
    assert np.nanmax(np.abs(u[20:-20] - 0.37)) < 0.03  # without the rule: 0 inside the stand, 1.1 m/s after


def test_a_vessel_that_really_stops_holds_no_fix():
    """A stop of 2 s between runs at 0.4 m/s (decelerating and accelerating over 1 s): the chord across
    the stop covers less than the speed around it would, so nothing is held; nor on a slow drift, a
    noisy track or a clean manoeuvring one."""
    def speed(t):
        return np.interp(t, [0, 8, 9, 11, 12, 20], [0.4, 0.4, 0.0, 0.0, 0.4, 0.4])
    t, north, east = _straight(speed)
    assert held_fixes(north, east, t).sum() == 0
    t, north, east = _straight(0.03)
    assert held_fixes(north, east, t).sum() == 0
    t, north, east, _ = manoeuvring_track()
    assert held_fixes(north, east, t).sum() == 0


def test_the_esso_osaka_held_fix_is_found():
    path = SHARED / "esso" / "turn_14-Oct-2020_15_21_57.csv"
    if not path.is_file():
        pytest.skip("../shared/data not present")
    from twin.formats import read_recording

    rec = read_recording(path)
    n, e, _ = local_ned(rec.gnss)
    held_t = rec.gnss.t[held_fixes(n, e, rec.gnss.t)]
    stand = held_t[(held_t > 79.0) & (held_t < 82.0)]
    assert stand.min() == pytest.approx(79.5, abs=0.05) and stand.max() == pytest.approx(81.3, abs=0.05)


def test_a_compass_calibration_leaves_the_heading_spikes_of_the_log():
    """Spikes are found on the heading as logged: under a strong compass deviation the calibrated
    heading is prepared without the logged spike, and its velocities are those of the spike-free log
    under the same calibration (a spike left in would move r by its jump over the derivative window)."""
    t, north, east, psi = manoeuvring_track(120.0, 5.0)
    spiked = psi.copy()
    spiked[300] += np.radians(30.0)
    vessel = load("yellowfish")
    vessel = replace(vessel, sensors=replace(vessel.sensors, compass_deviation_deg=(6.0, -4.0, 2.0, 1.0)))
    compiled = compile_vessel(vessel)
    faulty = prepare_for(_recording(t, north, east, spiked), compiled)
    clean = prepare_for(_recording(t, north, east, psi), compiled)
    assert dict(faulty.dropped)["heading spikes (outliers)"] == 1
    assert np.nanmax(np.abs(faulty.r - clean.r)) < 0.02
    assert np.nanmax(np.abs(faulty.psi - clean.psi)) < 0.02  # the spike left in: about 0.5 rad
