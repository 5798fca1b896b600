import errno
import os
from pathlib import Path

import pytest

import twin.vessel as vessel_mod
from twin.engine import batch
from twin.engine.mjcf import compile_vessel

SHARED = Path(__file__).resolve().parent.parent.parent / "shared"
# the files that take longest, first: xdist hands whole files to its workers in the order collected
# (--no-loadscope-reorder), and a long file started last keeps one worker busy alone after the other
# has finished
LONGEST_FIRST = ("test_sitl_ardupilot.py", "test_diagnose.py", "test_docs.py", "test_esso_engine.py", "test_sea.py",
                 "test_ident.py", "test_cli_ident.py", "test_esso_diagnose.py", "test_wind_per_log.py", "test_scale.py",
                 "test_kinematic.py", "test_esso_ident.py", "test_recordings.py", "test_scale_ray.py")


def pytest_collection_modifyitems(items):
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(LONGEST_FIRST)))  # stable: a file's own order kept


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


@pytest.fixture
def full_disk(monkeypatch):
    """files.write_bytes_atomic on a disk that fills up: `full_disk(share)` makes every write put down
    that share of its bytes and fail with ENOSPC."""
    from twin import files

    def fill(written_share: float = 0.0) -> None:
        class Full:
            def __init__(self, fd, mode):
                self.fh = open(fd, mode)  # os.fdopen is the one replaced

            def __enter__(self):
                return self

            def __exit__(self, *exc):
                self.fh.close()

            def write(self, data):
                self.fh.write(data[: int(len(data) * written_share)])
                raise OSError(errno.ENOSPC, "No space left on device")

        monkeypatch.setattr(files.os, "fdopen", Full)

    return fill

ROLLOUT_SHARE = pytest.StashKey()


def pytest_configure(config):
    """Each xdist worker's rollouts share the CPUs with the other workers: a rollout pool of a thread
    per CPU in every worker put twice as many busy threads as cores on the 2-core runner, and the
    suite took 488 s where with its share it takes 424 s (one run each, the same machine)."""
    workers = os.environ.get("PYTEST_XDIST_WORKER_COUNT")
    if workers:
        config.stash[ROLLOUT_SHARE] = share = batch.thread_limit(max(1, (os.cpu_count() or 1) // int(workers)))
        share.__enter__()


def pytest_unconfigure(config):
    share = config.stash.get(ROLLOUT_SHARE, None)
    if share is not None:
        share.__exit__(None, None, None)
