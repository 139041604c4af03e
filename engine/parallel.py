"""Thread-pool control and cooperative cancellation shared by the numerical code.

The calibration's least-squares steps multiply and decompose tall, thin
matrices (about 10^4 x 6); a multi-threaded BLAS gains nothing on them, and
its spinning threads take the cores the simulations need (measured on the
diagnosis of a record no candidate explains, 2 cores: 19.7 s with the default
BLAS threads, 13.6 s with one). :func:`single_threaded_blas` limits BLAS to
one thread for as long as any caller, in any thread, is inside it.

Work running on a thread whose result is no longer wanted (e.g. a candidate
fit made redundant by another) is stopped cooperatively: the thread runs
inside :func:`cancel_scope` with an event, and long loops call
:func:`raise_if_cancelled`, which raises :class:`Cancelled` once the event is set.

:class:`Runner` runs independent calls on a pool of threads, each inside its
own cancel scope (and, optionally, a per-thread context such as
:func:`engine.simulation.serial_kernel`), and hands back :class:`Task`
handles whose ``cancel()`` stops a call even once it has started. With one
job it runs nothing on threads: each call runs inline, when its result is
first asked for (:class:`Deferred`), so that cancelling a call before then
costs nothing.

:func:`thread_map` gives a map-like callable on a pool of threads for
independent evaluations (a finite-difference Jacobian's columns, a scan, the
fits of several candidates), in the form
``scipy.optimize.least_squares(workers=...)`` takes: results in the order of
the inputs, so the arithmetic is the same on one thread as on several. A map
called from one of the pool's own threads (a candidate's fit asking for its
Jacobian) runs on that thread: nested maps never wait on each other.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import CancelledError, Future, ThreadPoolExecutor
from contextlib import AbstractContextManager, contextmanager, nullcontext
from types import TracebackType
from typing import Any, Generic, ParamSpec, TypeVar

from threadpoolctl import threadpool_limits

__all__ = [
    "Cancelled",
    "Deferred",
    "Runner",
    "Task",
    "cancel_scope",
    "raise_if_cancelled",
    "run_in_scope",
    "single_threaded_blas",
    "thread_map",
]

#: A map-like callable: ``workers(fn, iterable)`` returns ``fn``'s results in the iterable's order.
MapLike = Callable[[Callable[[Any], Any], Iterable[Any]], Iterable[Any]]

_T = TypeVar("_T")
_P = ParamSpec("_P")
#: A factory of the context a pool thread enters around each call (e.g. ``serial_kernel``).
ThreadContext = Callable[[], AbstractContextManager[object]]

_LOCK = threading.Lock()
_SCOPE = threading.local()
#: Marks the threads of a :func:`thread_map` pool (``inside``): a map they call runs in place.
_MAP_THREAD = threading.local()
_depth = 0
_limiter: threadpool_limits | None = None


@contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Limit BLAS to one thread inside the context (re-entrant, thread-safe).

    The first entry sets the limit and the last exit restores the previous
    thread counts, so nested and concurrent users (e.g. candidate fits on
    several threads) never undo each other's limit.

    Notes
    -----
    OpenBLAS (0.3.31, pthreads) ignores a *raise* of its thread count asked
    from a thread other than the one that lowered it. When concurrent users
    (two service requests) leave in the other order, BLAS therefore stays at
    one thread; that is harmless here (every BLAS call of the engine is on
    small matrices) and no worse than the limit itself.
    """
    global _depth, _limiter
    with _LOCK:
        if _depth == 0:
            _limiter = threadpool_limits(limits=1, user_api="blas")
        _depth += 1
    try:
        yield
    finally:
        with _LOCK:
            _depth -= 1
            if _depth == 0 and _limiter is not None:
                _limiter.restore_original_limits()
                _limiter = None


class Cancelled(RuntimeError):
    """Raised by :func:`raise_if_cancelled` inside work whose result is no longer wanted."""


@contextmanager
def cancel_scope(event: threading.Event) -> Iterator[None]:
    """Make :func:`raise_if_cancelled` in this thread raise once ``event`` is set."""
    prev = getattr(_SCOPE, "event", None)
    _SCOPE.event = event
    try:
        yield
    finally:
        _SCOPE.event = prev


def raise_if_cancelled() -> None:
    """Raise :class:`Cancelled` when this thread's :func:`cancel_scope` event is set (else nothing)."""
    event = getattr(_SCOPE, "event", None)
    if event is not None and event.is_set():
        raise Cancelled("the result of this work is no longer wanted")


def run_in_scope(
    event: threading.Event, context: ThreadContext, fn: Callable[_P, _T], *args: _P.args, **kwargs: _P.kwargs
) -> _T:
    """Call ``fn(*args, **kwargs)`` inside ``context()`` and a :func:`cancel_scope` of ``event``.

    Parameters
    ----------
    event : threading.Event
        Setting it makes :func:`raise_if_cancelled` inside the call raise :class:`Cancelled`.
    context : callable
        Factory of a context manager entered around the call (``contextlib.nullcontext`` for none).
    fn : callable
        The call.

    Returns
    -------
    The call's result.
    """
    with context(), cancel_scope(event):
        return fn(*args, **kwargs)


class Task(Generic[_T]):
    """A call submitted to a thread pool; :meth:`cancel` also stops it once it has started.

    The call runs through :func:`run_in_scope` with the task's own event, so a
    started call stops at its next :func:`raise_if_cancelled` (raising
    :class:`Cancelled` from :meth:`result`); a call that has not started never
    runs (:meth:`result` raises ``concurrent.futures.CancelledError``).

    Parameters
    ----------
    executor : ThreadPoolExecutor
        The pool.
    context : callable
        Factory of the context entered around the call on the pool thread.
    fn : callable
        The call, with its arguments after it.
    """

    def __init__(
        self,
        executor: ThreadPoolExecutor,
        context: ThreadContext,
        fn: Callable[_P, _T],
        /,
        *args: _P.args,
        **kwargs: _P.kwargs,
    ):
        event = threading.Event()

        def call() -> _T:
            return run_in_scope(event, context, fn, *args, **kwargs)

        self._event = event
        self._future: Future[_T] = executor.submit(call)

    def result(self) -> _T:
        """Wait for the call and return its result (or raise what it raised)."""
        return self._future.result()

    def cancel(self) -> bool:
        """Ask the call to stop; True when it had not started (it then never runs)."""
        self._event.set()
        return self._future.cancel()


class Deferred(Generic[_T]):
    """The inline stand-in of a :class:`Task`: the call runs on the first :meth:`result`, never if cancelled first.

    Parameters
    ----------
    thunk : callable
        The call, without arguments.
    """

    def __init__(self, thunk: Callable[[], _T]):
        self._thunk: Callable[[], _T] | None = thunk
        self._cancelled = False
        self._value: _T

    def result(self) -> _T:
        """Run the call if it has not run yet and return its result.

        Raises
        ------
        concurrent.futures.CancelledError
            When the call was cancelled before it ran.
        """
        if self._cancelled:
            raise CancelledError("this call was cancelled before it ran")
        if self._thunk is not None:
            self._value, self._thunk = self._thunk(), None
        return self._value

    def cancel(self) -> bool:
        """Drop the call if it has not run yet; True when it had not."""
        if self._thunk is None:
            return False
        self._thunk, self._cancelled = None, True
        return True


class Runner:
    """Runs independent calls on ``n_jobs`` threads, or inline (deferred) when ``n_jobs == 1``.

    Use it as a context manager: on exit, every call still running is
    cancelled (e.g. after an error) and the pool is shut down.

    Parameters
    ----------
    n_jobs : int
        Calls at once; 1 runs each call inline, in the caller's thread (without
        ``thread_context`` and without a cancel scope), when its result is first asked for.
    thread_context : callable
        Factory of a context each pool thread enters around each call (default: none).
    thread_name_prefix : str
        Name prefix of the pool's threads.
    """

    def __init__(self, n_jobs: int, thread_context: ThreadContext = nullcontext, thread_name_prefix: str = "runner"):
        self.n_jobs = n_jobs
        self._context = thread_context
        self._ex = ThreadPoolExecutor(n_jobs, thread_name_prefix=thread_name_prefix) if n_jobs > 1 else None
        self._tasks: list[Task[Any]] = []

    def submit(self, fn: Callable[_P, _T], /, *args: _P.args, **kwargs: _P.kwargs) -> Task[_T] | Deferred[_T]:
        """A handle on ``fn(*args, **kwargs)`` with ``result()`` and ``cancel()``.

        On threads the call starts as soon as a thread is free; inline, it runs
        when its result is first asked for.
        """
        if self._ex is not None:
            task = Task(self._ex, self._context, fn, *args, **kwargs)
            self._tasks.append(task)
            return task
        return Deferred(lambda: fn(*args, **kwargs))

    def __enter__(self) -> Runner:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if self._ex is not None:
            for task in self._tasks:  # whatever is still running is no longer wanted (e.g. after an error)
                task.cancel()
            self._ex.shutdown(wait=True, cancel_futures=True)


@contextmanager
def thread_map(n_jobs: int, thread_name_prefix: str = "map") -> Iterator[MapLike | None]:
    """A map-like callable on ``n_jobs`` threads for as long as the context lasts; None for one job.

    For work that releases the GIL (a ``nogil`` numba kernel): ``workers(fn, items)`` runs
    ``fn`` on each item on the pool and returns the results as a list in the items' order (the
    form ``scipy.optimize.least_squares(workers=...)`` and :func:`scipy.optimize.approx_derivative`
    take). An exception raised by any call is raised by the map. Called from one of the pool's
    threads, the map runs on that thread (an outer map over candidates keeps the pool busy; their
    inner maps would otherwise wait for threads the outer one holds). Callers treat None as the
    builtin ``map`` (the same results, on the calling thread).
    """
    if n_jobs <= 1:
        yield None
        return

    def mark() -> None:
        _MAP_THREAD.inside = True

    with ThreadPoolExecutor(n_jobs, thread_name_prefix=thread_name_prefix, initializer=mark) as ex:

        def workers(fn: Callable[[Any], Any], items: Iterable[Any]) -> list[Any]:
            if getattr(_MAP_THREAD, "inside", False):
                return list(map(fn, items))
            return list(ex.map(fn, items))

        yield workers
