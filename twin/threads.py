"""One BLAS thread for the library's work, whose matrices are small; caches that threads can share.

A diagnosis, an identification and an evaluation solve thousands of small least-squares problems
(event templates of a few dozen samples, Jacobians of a few parameters). A multi-threaded BLAS
spends more on waking and synchronising its threads than on such a problem, and where the cores
are already busy (pytest-xdist, Ray workers, a second process) its threads wait on each other
(docs/method/decisions.md has the measurement). The limit holds only while a decorated call runs
(threadpoolctl restores the caller's); the CLI sets it for its whole process.

The library keeps what it computes again and again (a window's thrust commands, a recording's
rates, compiled models) in bounded stores. A program may call it from several threads at once
(identify fits its beliefs' weights side by side), so a store is locked while it is read or
changed, and a value is handed out as it was made or found, never looked up again after another
thread may have dropped it to make room.
"""
from __future__ import annotations

import os
import threading
from functools import wraps
from typing import Callable, Generic, Hashable, TypeVar

from threadpoolctl import threadpool_limits

F = TypeVar("F", bound=Callable)
V = TypeVar("V")


def one_blas_thread(fn: F) -> F:
    """`fn` run with BLAS (OpenBLAS, MKL, BLIS) limited to one thread, the caller's limits restored after."""
    @wraps(fn)
    def limited(*args, **kwargs):
        with threadpool_limits(limits=1, user_api="blas"):
            return fn(*args, **kwargs)
    return limited  # type: ignore[return-value]


# a BLAS reads its thread count when it is loaded: threadpoolctl reaches only those loaded already
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS")


def limit_process_blas_threads() -> None:
    """BLAS limited to one thread for the rest of this process and the processes it starts (the
    CLI's: the process is its own), unless the environment already says how many."""
    for name in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    if not any(os.environ[name] != "1" for name in BLAS_THREAD_VARIABLES):
        threadpool_limits(limits=1, user_api="blas")


class BoundedStore(Generic[V]):
    """Values by key, the oldest dropped first beyond `limit` entries or `max_bytes` (of values with
    an `nbytes`, numpy arrays), safe to share between threads (module docstring). A value is made
    outside the lock: two threads may make the same one at once, and the one stored first is kept."""

    def __init__(self, limit: int | None = None, max_bytes: int | None = None) -> None:
        self._values: dict[Hashable, V] = {}
        self._lock = threading.Lock()
        self._limit, self._max_bytes, self._bytes = limit, max_bytes, 0

    def get(self, key: Hashable, make: Callable[[], V]) -> V:
        """The value stored under `key`, made by `make()` and stored first if there is none."""
        with self._lock:
            if key in self._values:
                return self._values[key]
        value = make()
        with self._lock:
            if key in self._values:
                return self._values[key]
            self._values[key] = value
            self._bytes += getattr(value, "nbytes", 0)
            while len(self._values) > 1 and ((self._limit is not None and len(self._values) > self._limit) or
                                             (self._max_bytes is not None and self._bytes > self._max_bytes)):
                self._bytes -= getattr(self._values.pop(next(iter(self._values))), "nbytes", 0)
        return value

    def peek(self, key: Hashable) -> V | None:
        """The value stored under `key`, or None (nothing is made or stored)."""
        with self._lock:
            return self._values.get(key)

    def __len__(self) -> int:
        return len(self._values)
