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
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

from threadpoolctl import threadpool_limits

__all__ = ["Cancelled", "cancel_scope", "raise_if_cancelled", "single_threaded_blas"]

_LOCK = threading.Lock()
_SCOPE = threading.local()
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
