from pathlib import Path

import pytest

import twin.vessel as vessel_mod
from twin.engine.mjcf import compile_vessel

SHARED = Path(__file__).resolve().parent.parent.parent / "shared"


@pytest.fixture(scope="session")
def yellowfish():
    return compile_vessel(vessel_mod.load("yellowfish"))


@pytest.fixture(scope="session")
def cybership():
    return compile_vessel(vessel_mod.load("cybership1"))


@pytest.fixture
def shared_dir():
    if not SHARED.is_dir():
        pytest.skip("../shared is not present")
    return SHARED
