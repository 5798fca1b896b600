"""GNSS fixes off their track and heading spikes: found where injected, never on hard manoeuvres,
left out of preparation and counted where the user sees them."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from twin.prepare import prepare
from twin.prepare.outliers import FLOOR_GNSS_M, describe, gnss_outliers, heading_spikes
from twin.prepare.prepared import outlier_counts as counted
from twin.recording import Recording, Stream

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
    assert counted(rec) == {"gnss": 3, "heading": 1}
    assert any(f"{FLOOR_GNSS_M:g} m" in line and line.endswith(": 3") for line in describe(counted(rec)))


def test_shared_real_logs_have_no_outliers():
    """The real BlueBoat and Esso Osaka logs: nothing is left out (the rule changes nothing there)."""
    if not SHARED.is_dir():
        pytest.skip("../shared/data not present")
    from twin.formats import read_recording

    paths = sorted((SHARED / "blueboat").glob("*.csv"))[:4] + sorted((SHARED / "esso").glob("turn_14-Sep*.csv"))[:2]
    for path in paths:
        assert counted(read_recording(path)) == {"gnss": 0, "heading": 0}, path.name
