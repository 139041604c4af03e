"""The synchronous ``POST /v1/diagnose``: a few diagnoses at once, each in a worker process, each with a time limit.

Beyond :attr:`Settings.max_sync_diagnoses` running at once, a request is refused at once
(429 with ``Retry-After``) rather than queued behind the others while its client waits; a
diagnosis that runs past :attr:`Settings.sync_diagnose_timeout` has its worker process
terminated (so its core is free) and is answered 504 with the way to run it without a limit
(``POST /v1/diagnoses``, a job). A diagnosis whose client has gone is cancelled by the HTTP layer
(:meth:`SyncDiagnoses.start` gives the future to cancel): its worker is terminated and its slot
given back at once, not when the diagnosis would have ended.
"""

from __future__ import annotations

import logging
import threading
from concurrent.futures import Future
from concurrent.futures import TimeoutError as FutureTimeout
from typing import Any

from pebble import ProcessExpired, ProcessPool

from app.jobs.manager import new_process_pool
from app.services.diagnosis_requests import DiagnosisRequest, run_sync
from app.services.errors import QueueFullError, TimeLimitError

logger = logging.getLogger(__name__)

__all__ = ["SyncDiagnoses"]

#: Seconds a refused client is told to wait (``Retry-After``): about one diagnosis of a single-effect record.
RETRY_AFTER = 15


class SyncDiagnoses:
    """Runs synchronous diagnoses in a pool of worker processes, at most ``max_concurrent`` at once.

    Parameters
    ----------
    max_concurrent : int
        Diagnoses running at once; one more is refused with :class:`QueueFullError` (429).
    timeout : float
        Time limit of one diagnosis [s]; beyond it :class:`TimeLimitError` (504).
    """

    def __init__(self, max_concurrent: int, timeout: float) -> None:
        if max_concurrent < 1 or not timeout > 0:
            raise ValueError("max_concurrent must be >= 1 and timeout > 0")
        self.max_concurrent = max_concurrent
        self.timeout = float(timeout)
        self._slots = threading.BoundedSemaphore(max_concurrent)
        self._lock = threading.Lock()
        self._running = 0
        self._pool: ProcessPool | None = new_process_pool(max_concurrent)  # started here: see new_process_pool

    @property
    def running(self) -> int:
        """Synchronous diagnoses running now."""
        with self._lock:
            return self._running

    def start(self, request: DiagnosisRequest) -> Future[dict[str, Any]]:
        """Take a slot and start the diagnosis in a worker process; its future (:meth:`result` reads it).

        The slot is given back when the future ends, however it ends: done, failed, past the time limit, or
        cancelled (``future.cancel()`` by a caller whose client has gone: the worker process is terminated, so
        its core is free too, and its result would be discarded).

        Raises
        ------
        QueueFullError
            Every slot is taken (429).
        """
        if not self._slots.acquire(blocking=False):
            raise QueueFullError(
                f"{self.max_concurrent} synchronous diagnoses are running (the limit); retry later, or submit "
                "the record as a job with POST /v1/diagnoses, which queues it",
                retry_after=RETRY_AFTER,
            )
        with self._lock:
            self._running += 1
        try:
            future: Future[dict[str, Any]] = self._get_pool().schedule(run_sync, args=(request,), timeout=self.timeout)
        except BaseException:
            self._release(None)
            raise
        future.add_done_callback(self._release)
        return future

    def result(self, future: Future[dict[str, Any]], timeout: float | None = None) -> dict[str, Any]:
        """The answer of a diagnosis :meth:`start` started (waiting up to ``timeout`` [s] for it; ``None``: until
        it ends).

        Raises
        ------
        TimeLimitError
            It ran past the synchronous limit and was stopped (504).
        concurrent.futures.CancelledError
            It was cancelled.
        """
        try:
            return future.result(timeout)
        except FutureTimeout:
            if not future.done():
                raise  # the caller's own timeout, not the diagnosis's limit
            raise TimeLimitError(
                f"the diagnosis took longer than the synchronous limit of {self.timeout:g} s and was stopped; "
                "submit it as a job with POST /v1/diagnoses (no limit, progress, cancellable)"
            ) from None
        except ProcessExpired as exc:
            raise RuntimeError(f"the worker process running the diagnosis died ({exc})") from exc

    def run(self, request: DiagnosisRequest) -> dict[str, Any]:
        """Diagnose (blocking the calling thread); the answer of ``POST /v1/diagnose``."""
        return self.result(self.start(request))

    def _release(self, future: Future[dict[str, Any]] | None) -> None:
        """Give a slot back (a future's done-callback: called once per future)."""
        with self._lock:
            self._running -= 1
        self._slots.release()

    def close(self) -> None:
        """Terminate the worker processes (running diagnoses are stopped)."""
        with self._lock:
            pool, self._pool = self._pool, None
        if pool is not None:
            pool.stop()
            pool.join(timeout=10)

    def _get_pool(self) -> ProcessPool:
        with self._lock:
            if self._pool is None:
                raise RuntimeError("the synchronous diagnoses are closed (the service is shutting down)")
            return self._pool
