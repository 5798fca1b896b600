"""The library's heavy calls run with one BLAS thread and give the caller's limit back."""
import numpy as np
import scipy.linalg  # noqa: F401  (its own OpenBLAS, loaded as the library's modules load it)
from threadpoolctl import threadpool_info, threadpool_limits

from twin.threads import one_blas_thread


def _blas_threads() -> set[int]:
    return {lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"}


def test_a_decorated_call_runs_on_one_blas_thread_and_restores_the_callers_limit():
    seen = []

    @one_blas_thread
    def work(a):
        seen.append(_blas_threads())
        return np.linalg.svd(a, compute_uv=False)

    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        s = work(np.eye(3) * 2.0)
        after = _blas_threads()
    assert seen == [{1}]
    assert after == before and before <= {2}  # a machine with one core reports 1
    assert s.tolist() == [2.0, 2.0, 2.0]
    assert work.__name__ == "work"


def test_the_library_entry_points_are_limited():
    from twin.diagnose.doctor import diagnose
    from twin.fit.evaluate import evaluate
    from twin.ident.identify import identify

    assert all(getattr(f, "__wrapped__", None) is not None for f in (diagnose, evaluate, identify))
