"""engine.parallel: the BLAS thread limit is re-entrant and safe across threads."""

from __future__ import annotations

import threading

from threadpoolctl import threadpool_info

from engine.parallel import single_threaded_blas


def blas_threads() -> list[int]:
    return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]


def test_limit_is_reentrant_and_restored():
    before = blas_threads()
    with single_threaded_blas():
        assert all(n == 1 for n in blas_threads())
        with single_threaded_blas():
            assert all(n == 1 for n in blas_threads())
        assert all(n == 1 for n in blas_threads()), "the inner exit must not lift the outer limit"
    assert blas_threads() == before


def test_a_thread_leaving_does_not_lift_another_threads_limit():
    before = blas_threads()
    inside, release = threading.Event(), threading.Event()
    seen: list[list[int]] = []

    def other():
        with single_threaded_blas():
            inside.set()
            release.wait(10)
            seen.append(blas_threads())

    t = threading.Thread(target=other)
    with single_threaded_blas():
        t.start()
        inside.wait(10)
    # this thread has left; the other is still inside and must still be limited
    release.set()
    t.join(10)
    assert seen and all(n == 1 for n in seen[0])
    # (the last exit was in the other thread: OpenBLAS may keep one thread, see the Notes)
    assert all(n <= m for n, m in zip(blas_threads(), before))


def test_cancel_scope_raises_only_once_set_and_only_inside():
    import pytest

    from engine.parallel import Cancelled, cancel_scope, raise_if_cancelled

    ev = threading.Event()
    with cancel_scope(ev):
        raise_if_cancelled()
        ev.set()
        with pytest.raises(Cancelled):
            raise_if_cancelled()
    raise_if_cancelled()  # outside the scope nothing is cancelled
