"""One BLAS thread for the library's work, whose matrices are small.

A diagnosis, an identification and an evaluation solve thousands of small least-squares problems
(event templates of a few dozen samples, Jacobians of a few parameters). A multi-threaded BLAS
spends more on waking and synchronising its threads than on such a problem, and where the cores
are already busy (pytest-xdist, Ray workers, a second process) its threads wait on each other
(docs/method/decisions.md has the measurement). The limit holds only while a decorated call runs
(threadpoolctl restores the caller's); the CLI sets it for its whole process.
"""
from __future__ import annotations

import os
from functools import wraps
from typing import Callable, TypeVar

from threadpoolctl import threadpool_limits

F = TypeVar("F", bound=Callable)


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
