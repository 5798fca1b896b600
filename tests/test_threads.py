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


def test_a_bounded_store_drops_its_oldest_beyond_its_count_or_its_bytes():
    from twin.threads import BoundedStore

    by_count = BoundedStore(limit=2)
    for k in range(3):
        by_count.get(k, lambda k=k: k * 10)
    assert len(by_count) == 2 and by_count.get(0, lambda: -1) == -1  # 0 was dropped, and is made again
    by_bytes = BoundedStore(max_bytes=3 * 800)
    for k in range(5):
        by_bytes.get(k, lambda: np.zeros(100))  # 800 bytes each
    assert len(by_bytes) == 3
    assert by_bytes.get(4, lambda: np.ones(1)).shape == (100,)  # the newest is kept


def test_a_bounded_store_shared_by_threads_hands_out_one_value_per_key():
    import threading

    from twin.threads import BoundedStore

    store, made, seen = BoundedStore(limit=1000), [], []
    start = threading.Barrier(4)

    def work(tag):
        start.wait()
        for k in range(200):
            seen.append((k, store.get(k, lambda k=k: made.append(k) or (k, tag))))

    threads = [threading.Thread(target=work, args=(t,)) for t in range(4)]
    [t.start() for t in threads]
    [t.join() for t in threads]
    first = {}
    for k, value in seen:
        assert value[0] == k and first.setdefault(k, value) == value  # every thread got the stored one
    assert len(first) == 200 and len(store) == 200
