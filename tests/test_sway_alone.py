"""The sway equation alone (twin/fit/sway_alone.py): driven by known u, r and thrust, it recovers the
sway law a recording was made with, and a form that lacks one of its terms scores visibly lower."""
import numpy as np
import pytest

from twin.errors import TwinError
from twin.fit import sway_alone as sa

TRUE = {"v": 2.0, "|v|v": 6.0, "ur": 0.5, "r": 0.3, "dT": 0.004}


def _recording(seed: int, law: dict) -> sa.SwayDrivers:
    rng = np.random.default_rng(seed)
    n, h = 3000, 0.1
    t = np.arange(n) * h

    def smooth(scale):  # a sum of slow sines: a boat's inputs, not white noise
        return scale * sum(np.sin(2 * np.pi * f * t + p) for f, p in zip(rng.uniform(0.01, 0.2, 4),
                                                                        rng.uniform(0, 2 * np.pi, 4))) / 2
    u, r, dT = 1.0 + smooth(0.8), smooth(0.3), smooth(20.0)
    blank = sa.SwayDrivers(u, np.zeros(n), r, dT, np.zeros(n, int), h)
    whole = sa._stack([blank], [(0, 0, n - 1)])
    v = sa.free_runs(law, whole)[0]  # one free run over the whole record: the truth's own sway
    return sa.SwayDrivers(u, v, r, dT, np.zeros(n, int), h)


def test_the_law_a_recording_was_made_with_is_recovered_and_a_missing_term_shows():
    drivers = [_recording(1, TRUE), _recording(2, TRUE)]
    found = sa.fit(drivers, tuple(TRUE))
    for name, value in TRUE.items():
        assert found.coefficients[name] == pytest.approx(value, rel=0.01), name
    assert found.r2 > 0.999
    assert sa.score(found.coefficients, [_recording(3, TRUE)]) > 0.999  # another run of the same hull
    without_ur = sa.fit(drivers, ("v", "|v|v", "r", "dT"))
    assert without_ur.r2 < found.r2 - 0.05


def test_unknown_terms_and_records_too_short_are_refused():
    drivers = [_recording(1, TRUE)]
    with pytest.raises(TwinError, match="sway terms must be some of"):
        sa.fit(drivers, ("v", "vvv"))
    with pytest.raises(TwinError, match="no free run of 1000 s"):
        sa.fit(drivers, ("v",), horizon_s=1000.0)
