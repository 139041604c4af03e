"""In-process background jobs on a thread pool: queued -> running -> done | failed.

A job is a function ``fn(progress)`` run on one of ``workers`` threads; it reports
progress through ``progress(fraction, stage)``. The manager keeps every job's
state, progress (0..1, never decreasing), current stage, error text and result
in memory; jobs are forgotten when the process stops (what they produced, e.g. a
stored pattern set, is not).
"""

from __future__ import annotations

import builtins
import logging
import threading
import uuid
from collections import OrderedDict
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from enum import StrEnum
from typing import Any

from app.services.errors import NotFoundError, QueueFullError

logger = logging.getLogger(__name__)

ProgressFn = Callable[[float, str], None]


class JobState(StrEnum):
    queued = "queued"
    running = "running"
    done = "done"
    failed = "failed"


@dataclass(frozen=True)
class Job:
    """Snapshot of one job (the manager hands out copies; they do not change)."""

    id: str
    kind: str
    state: JobState
    progress: float
    stage: str | None
    error: str | None
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    meta: dict[str, Any]
    result: Any = None

    @property
    def finished(self) -> bool:
        return self.state in (JobState.done, JobState.failed)


def _now() -> datetime:
    return datetime.now(UTC)


class JobManager:
    """Runs jobs on ``workers`` background threads.

    Parameters
    ----------
    workers : int
        Threads that run jobs; further jobs wait in state ``queued`` (the service's
        ``Settings.workers``).
    max_pending : int
        Most queued plus running jobs; :meth:`submit` raises :class:`QueueFullError` beyond
        (the service's ``Settings.max_pending_jobs``).
    keep_finished : int
        Finished jobs remembered (oldest forgotten first).
    """

    def __init__(self, workers: int, max_pending: int, keep_finished: int = 1000) -> None:
        if workers < 1 or max_pending < 1 or keep_finished < 0:
            raise ValueError("workers and max_pending must be >= 1, keep_finished >= 0")
        self._executor = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="backlash-job")
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)  # notified whenever a job changes
        self._jobs: OrderedDict[str, Job] = OrderedDict()
        self._max_pending = max_pending
        self._keep_finished = keep_finished
        self._closed = False

    # -- public API -------------------------------------------------------------

    def submit(self, fn: Callable[[ProgressFn], Any], *, kind: str, meta: dict[str, Any] | None = None) -> Job:
        """Queue ``fn(progress)``; return the queued job's snapshot."""
        job = Job(
            id=uuid.uuid4().hex,
            kind=kind,
            state=JobState.queued,
            progress=0.0,
            stage="queued",
            error=None,
            created_at=_now(),
            started_at=None,
            finished_at=None,
            meta=dict(meta or {}),
        )
        with self._lock:
            if self._closed:
                raise QueueFullError("the server is shutting down and accepts no new jobs")
            pending = sum(1 for j in self._jobs.values() if not j.finished)
            if pending >= self._max_pending:
                raise QueueFullError(
                    f"{pending} training jobs are queued or running (the limit is {self._max_pending}); "
                    "wait for some to finish and retry"
                )
            self._jobs[job.id] = job
            self._forget_old()
            self._changed.notify_all()
        self._executor.submit(self._run, job.id, fn)
        logger.info("job %s (%s) queued", job.id, kind)
        return job

    def get(self, job_id: str) -> Job:
        with self._lock:
            job = self._jobs.get(job_id)
        if job is None:
            raise NotFoundError(
                f"no job with id {job_id!r}; jobs are kept in memory and forgotten when the server restarts "
                "(a finished training job's pattern set stays in the store)"
            )
        return job

    def wait(self, job_id: str, timeout: float | None = None) -> Job:
        """Block until the job has finished or ``timeout`` [s] has passed; return its snapshot then.

        Raises
        ------
        NotFoundError
            No job ``job_id`` is remembered.
        """
        self.get(job_id)
        with self._changed:
            self._changed.wait_for(lambda: job_id not in self._jobs or self._jobs[job_id].finished, timeout)
        return self.get(job_id)

    def list(self) -> list[Job]:
        """All remembered jobs, newest first."""
        with self._lock:
            return list(reversed(self._jobs.values()))

    def find(self, **meta: Any) -> builtins.list[Job]:
        """Remembered jobs whose ``meta`` holds all the given items, newest first."""
        return [j for j in self.list() if all(j.meta.get(k) == v for k, v in meta.items())]

    def shutdown(self, wait: bool = True) -> None:
        """Stop accepting jobs, fail the queued ones, and (if ``wait``) wait for the running ones."""
        with self._lock:
            self._closed = True
            for job_id, job in self._jobs.items():
                if job.state is JobState.queued:
                    self._jobs[job_id] = replace(
                        job,
                        state=JobState.failed,
                        error="the server shut down before the job started",
                        finished_at=_now(),
                    )
            self._changed.notify_all()
        self._executor.shutdown(wait=wait, cancel_futures=True)

    # -- internals --------------------------------------------------------------

    def _update(self, job_id: str, **changes: Any) -> Job:
        with self._lock:
            job = replace(self._jobs[job_id], **changes)
            self._jobs[job_id] = job
            self._changed.notify_all()
            return job

    def _forget_old(self) -> None:
        finished = [k for k, j in self._jobs.items() if j.finished]
        for k in finished[: max(0, len(finished) - self._keep_finished)]:
            del self._jobs[k]

    def _run(self, job_id: str, fn: Callable[[ProgressFn], Any]) -> None:
        with self._lock:
            job = self._jobs.get(job_id)
            if job is None or job.state is not JobState.queued:  # failed by shutdown
                return
        self._update(job_id, state=JobState.running, started_at=_now(), stage="starting")
        logger.info("job %s running", job_id)

        def progress(fraction: float, stage: str | None = None) -> None:
            with self._lock:
                cur = self._jobs[job_id]
                value = min(1.0, max(cur.progress, float(fraction)))  # clamp, never decrease
                self._jobs[job_id] = replace(cur, progress=value, stage=stage if stage is not None else cur.stage)
                self._changed.notify_all()

        try:
            result = fn(progress)
        except Exception as exc:  # the job's failure is data, not a crash of the server
            error = f"{type(exc).__name__}: {exc}"
            self._update(job_id, state=JobState.failed, error=error, finished_at=_now())
            logger.warning("job %s failed: %s", job_id, error, exc_info=True)
            return
        self._update(job_id, state=JobState.done, progress=1.0, stage="done", result=result, finished_at=_now())
        logger.info("job %s done", job_id)
