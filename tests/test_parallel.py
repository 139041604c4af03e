"""engine.parallel: the BLAS thread limit, cooperative cancellation and the thread runner."""

from __future__ import annotations

import threading
import time
from concurrent.futures import CancelledError
from contextlib import contextmanager

import pytest
from threadpoolctl import threadpool_info

from engine.parallel import Cancelled, Runner, cancel_scope, raise_if_cancelled, single_threaded_blas, thread_map


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
    assert all(n <= m for n, m in zip(blas_threads(), before, strict=True))


def test_cancel_scope_raises_only_once_set_and_only_inside():
    ev = threading.Event()
    with cancel_scope(ev):
        raise_if_cancelled()
        ev.set()
        with pytest.raises(Cancelled):
            raise_if_cancelled()
    raise_if_cancelled()  # outside the scope nothing is cancelled


def test_inline_runner_defers_and_cancels():
    calls: list[str] = []
    with Runner(1) as runner:
        a = runner.submit(calls.append, "a")
        b = runner.submit(calls.append, "b")
        assert calls == []  # nothing runs before its result is asked for
        a.result()
        assert b.cancel()
        assert calls == ["a"]
        with pytest.raises(CancelledError):  # a dropped call has no result
            b.result()
        assert not a.cancel()  # it has run already
    with Runner(2) as runner:
        assert runner.submit(sum, [1, 2]).result() == 3


def test_a_started_task_stops_at_its_next_check_when_cancelled():
    started = threading.Event()
    checks: list[int] = []

    def work() -> str:
        started.set()
        for i in range(10_000):
            checks.append(i)
            raise_if_cancelled()
            if i == 0:
                assert cancelled.wait(10)  # hold the first step until the task is cancelled
        return "ran to the end"

    cancelled = threading.Event()
    with Runner(2) as runner:
        task = runner.submit(work)
        assert started.wait(10)
        assert not task.cancel()  # running: it cannot be dropped, only stopped
        cancelled.set()
        with pytest.raises(Cancelled):
            task.result()
    assert checks == [0, 1]  # the check after the cancellation raised


def test_a_task_cancelled_before_it_starts_never_runs():
    release = threading.Event()
    ran: list[str] = []
    with Runner(2) as runner:
        busy = [runner.submit(release.wait, 10) for _ in range(2)]  # both threads taken
        queued = runner.submit(ran.append, "queued")
        assert queued.cancel()
        release.set()
        assert all(b.result() for b in busy)
        with pytest.raises(CancelledError):
            queued.result()
    assert ran == []


def test_runner_threads_enter_the_thread_context_around_each_call():
    entered: list[str] = []

    @contextmanager
    def context():
        entered.append(threading.current_thread().name)
        yield

    with Runner(2, thread_context=context, thread_name_prefix="worker") as runner:
        names = [runner.submit(lambda: threading.current_thread().name).result() for _ in range(3)]
    assert entered == names and all(n.startswith("worker") for n in names)
    with Runner(1, thread_context=context) as runner:  # inline: in the caller's thread, no context
        assert runner.submit(lambda: threading.current_thread().name).result() == threading.current_thread().name
    assert len(entered) == 3


def test_leaving_the_runner_stops_tasks_still_running():
    started, stopped = threading.Event(), threading.Event()

    def work() -> None:
        started.set()
        try:
            for _ in range(10_000):  # until the runner's exit cancels it (bounded: a broken exit fails, not hangs)
                raise_if_cancelled()
                time.sleep(0.001)
        except Cancelled:
            stopped.set()
            raise

    with Runner(2) as runner:
        runner.submit(work)
        assert started.wait(10)
    assert stopped.is_set()  # the exit cancelled it and waited for it


def test_thread_map_keeps_the_order_runs_nested_maps_in_place_and_raises():
    with thread_map(1) as none:
        assert none is None  # one job: the caller uses the builtin map
    with thread_map(2) as workers:
        assert workers is not None
        names: set[str] = set()

        def inner(i: int) -> list[str]:
            names.add(threading.current_thread().name)
            # a map asked for on a pool thread runs there: the outer map holds every thread
            return list(workers(lambda j: f"{i}.{j}:{threading.current_thread().name}", range(3)))

        out = workers(inner, range(6))
        assert [[x.split(":")[0] for x in row] for row in out] == [[f"{i}.{j}" for j in range(3)] for i in range(6)]
        assert all(len({x.split(":")[1] for x in row}) == 1 for row in out)
        assert all(n.startswith("map") for n in names)

        def boom(i: int) -> int:
            if i == 3:
                raise FloatingPointError("diverged")
            return i

        with pytest.raises(FloatingPointError, match="diverged"):
            workers(boom, range(5))


def test_a_plant_diagnosis_refuses_fewer_than_one_thread():
    from engine.diagnosis.plant_gap import simulation_pool
    from engine.plants import get_plant

    with pytest.raises(ValueError, match="jobs must be at least 1"), simulation_pool(get_plant("emps"), 0):
        pass
    with simulation_pool(get_plant("brfd"), 2) as workers:
        assert workers is None  # a plant whose simulations stay on one thread
