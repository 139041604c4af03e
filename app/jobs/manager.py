"""Runs background jobs and keeps them in SQLite: queued -> running -> done | failed | cancelled | interrupted.

A job is a kind (:class:`JobKind`) and a JSON *spec*; the spec is stored with the job, so a job
that did not finish can be run again (:meth:`JobManager.retry`), also after a restart. Two
places run jobs:

* ``process`` kinds (a diagnosis; a training by default) run in pools of worker processes
  (`pebble <https://pebble.readthedocs.io>`_), one pool per kind of work; cancelling a running one
  terminates its worker process, so its cores are free at once, and the pool starts another; and
  the service's own threads stay free for requests (a long training in a thread would hold the
  interpreter and slow every answer).
* ``thread`` kinds run on ``workers`` threads of the service process (a training that only waits
  for a Dask cluster, or one configured so); a cancelled one stops at its next progress report
  (:class:`JobCancelled` is raised inside it).

The process that runs a job writes its progress into the database, so the service reads
progress the same way for both places. When the service starts, jobs that were queued or
running when it last stopped are marked ``interrupted`` with a message
(:meth:`JobManager.recover`): nothing else would ever finish them.
"""

from __future__ import annotations

import builtins
import ctypes
import functools
import logging
import multiprocessing
import os
import signal
import sqlite3
import sys
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import CancelledError, Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from pebble import ProcessExpired, ProcessPool

from app.db.jobs import Job, JobRepository, JobState
from app.services.errors import ConflictError, NotFoundError, QueueFullError
from engine.storage import PatternStore

logger = logging.getLogger(__name__)

__all__ = [
    "JobCancelled",
    "JobKind",
    "JobManager",
    "ProgressFn",
    "RowsFn",
    "die_with_parent",
    "new_process_pool",
    "run_in_process",
]

ProgressFn = Callable[[float, str], None]
#: ``with_rows(conn, job)`` of :meth:`JobManager.submit`: writes the rows that belong with a new job, in its transaction.
RowsFn = Callable[[sqlite3.Connection, Job], None]
#: ``run(spec, progress)`` of a thread kind; returns items merged into the job's meta.
ThreadRunner = Callable[[dict[str, Any], ProgressFn], dict[str, Any] | None]
#: ``run(db_path, spec, progress)`` of a process kind: a module-level function (it is pickled by name).
ProcessRunner = Callable[[Path, dict[str, Any], ProgressFn], dict[str, Any] | None]

#: ``prctl`` option: the signal a process gets when its parent ends (linux/prctl.h).
PR_SET_PDEATHSIG = 1
#: How often [s] a waiting client re-reads a job it waits for.
POLL_INTERVAL = 0.05


class JobCancelled(Exception):
    """Raised inside a thread job at its next progress report once a client has cancelled it."""


class JobError(Exception):
    """A process job's failure as it comes back from its worker: ``"<type>: <message>"`` (always picklable)."""


@dataclass(frozen=True)
class JobKind:
    """One kind of job: its name, where it runs and its runner.

    Attributes
    ----------
    name : str
        The job's ``kind`` (e.g. ``train_pattern_set``, ``diagnose``).
    runs_in : {"thread", "process"}
        Where it runs (see the module docstring).
    run : callable
        :data:`ThreadRunner` or :data:`ProcessRunner`.
    pool : str
        The process pool a ``process`` kind runs in (the manager's ``pools`` give their sizes), so that
        kinds of work do not queue behind each other.
    """

    name: str
    runs_in: Literal["thread", "process"]
    run: Callable[..., dict[str, Any] | None]
    pool: str = "default"


def die_with_parent(parent: int) -> None:
    """Initializer of the worker processes: end when the service process ``parent`` ends, however it ends (Linux).

    Without it a worker of a killed service would run on as an orphan and could store a result
    after the next service has marked its job interrupted. ``PR_SET_PDEATHSIG`` asks the kernel to
    send SIGKILL when the parent goes; elsewhere nothing is done. (The parent is compared by pid,
    not with 1: in a container the service itself is pid 1.)
    """
    if not sys.platform.startswith("linux"):
        return
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL) != 0:
        logger.warning("worker %d cannot ask to end with its parent (errno %d)", os.getpid(), ctypes.get_errno())
    if os.getppid() != parent:  # the parent died before the request took effect: go now
        os._exit(1)


def _ready() -> None:
    """The first task of a pool: makes the pool start its workers now."""


def new_process_pool(workers: int) -> ProcessPool:
    """A started pool of ``workers`` spawned worker processes that end with the service (:func:`die_with_parent`).

    Call it from a thread that lives as long as the pool (the service's main thread): the kernel
    ties a child's parent-death signal to the thread that started it, and the pool starts its first
    workers in the calling thread. Spawned, not forked: the service process has threads (uvicorn,
    numba), and forking it is not safe.
    """
    pool = ProcessPool(
        max_workers=workers,
        initializer=die_with_parent,
        initargs=(os.getpid(),),
        context=multiprocessing.get_context("spawn"),
    )
    pool.schedule(_ready)
    return pool


def run_in_process(db_path: Path, job_id: str, run: ProcessRunner, spec: dict[str, Any]) -> None:
    """Entry point of a job in a worker process: mark it running, run it, store ``done`` (or raise)."""
    jobs = JobRepository(PatternStore(db_path))
    if not jobs.start(job_id):
        return  # cancelled (or interrupted) before it started

    def progress(fraction: float, stage: str | None = None) -> None:
        jobs.progress(job_id, fraction, stage)

    try:
        meta = run(db_path, spec, progress) or {}
    except Exception as exc:  # sent back as text: not every exception survives pickling
        raise JobError(f"{type(exc).__name__}: {exc}") from None
    jobs.finish(job_id, **meta)


class JobManager:
    """Runs the jobs of the registered kinds and keeps their states in the store's file.

    Parameters
    ----------
    store : PatternStore
        The SQLite file of the service.
    kinds : mapping of str to JobKind
        The kinds of job it runs.
    workers : int
        Threads for ``thread`` kinds.
    pools : mapping of str to int
        Worker processes of each process pool the ``process`` kinds name (``Settings.workers`` for
        training, ``Settings.diagnosis_workers`` for diagnoses).
    max_pending : int
        Most queued plus running jobs; :meth:`submit` raises :class:`QueueFullError` beyond.
    """

    def __init__(
        self,
        store: PatternStore,
        kinds: Mapping[str, JobKind],
        *,
        workers: int,
        pools: Mapping[str, int],
        max_pending: int,
    ) -> None:
        if workers < 1 or max_pending < 1 or any(n < 1 for n in pools.values()):
            raise ValueError("workers, every pool's size and max_pending must be >= 1")
        missing = {k.pool for k in kinds.values() if k.runs_in == "process"} - set(pools)
        if missing:
            raise ValueError(f"no size given for the process pool(s) {sorted(missing)}")
        self.store = store
        self.repo = JobRepository(store)
        self._kinds = dict(kinds)
        self._threads = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="backlash-job")
        used = {k.pool for k in kinds.values() if k.runs_in == "process"}
        self._pools = {name: new_process_pool(size) for name, size in pools.items() if name in used}
        self._max_pending = max_pending
        self._lock = threading.Lock()
        self._futures: dict[str, Future[Any]] = {}
        self._cancelled: set[str] = set()
        self._closed = False

    # -- life cycle -------------------------------------------------------------------------

    def recover(self) -> builtins.list[str]:
        """Mark the jobs a previous run of the service left queued or running as ``interrupted``."""
        ids = self.repo.interrupt_unfinished(
            "the service stopped before this job finished; POST /v1/jobs/{id}/retry runs it again"
        )
        for job_id in ids:
            logger.warning("job %s was interrupted by a restart of the service", job_id)
        return ids

    def shutdown(self, wait: bool = True) -> None:
        """Stop accepting jobs; queued and running jobs end ``interrupted`` (a retry runs them again).

        Running diagnoses' worker processes are terminated; running thread jobs stop at their next
        progress report (``wait``: wait for that).
        """
        with self._lock:
            self._closed = True
            futures = dict(self._futures)
            self._cancelled.update(futures)
        for future in futures.values():
            future.cancel()
        for pool in self._pools.values():
            pool.stop()
        for pool in self._pools.values():
            pool.join(timeout=10)
        self._threads.shutdown(wait=wait, cancel_futures=True)
        for job_id in self.repo.interrupt_unfinished(
            "the service shut down before this job finished; POST /v1/jobs/{id}/retry runs it again"
        ):
            logger.info("job %s interrupted by the shutdown", job_id)

    # -- public API ----------------------------------------------------------------------------

    def submit(
        self,
        kind: str,
        spec: dict[str, Any],
        *,
        meta: dict[str, Any] | None = None,
        retry_of: str | None = None,
        with_rows: RowsFn | None = None,
    ) -> Job:
        """Store a queued job of ``kind`` and start it when a worker is free; return its snapshot.

        The queue's limit is checked, the job inserted and ``with_rows(conn, job)`` run (the rows that belong
        with the job: a diagnosis's record and its diagnosis) in one write transaction: a refused job stores
        nothing, and a stored job is never without its rows. The job starts only once they are committed.

        Raises
        ------
        QueueFullError
            Too many jobs are queued or running, or the service is shutting down.
        """
        job_kind = self._kinds[kind]
        with self._lock:
            if self._closed:
                raise QueueFullError("the server is shutting down and accepts no new jobs")
            with self.store.writing() as conn:
                pending = self.repo.count_unfinished(conn)
                if pending >= self._max_pending:
                    raise QueueFullError(
                        f"{pending} jobs are queued or running (the limit is {self._max_pending}); "
                        "wait for some to finish and retry"
                    )
                job = self.repo.create(kind, meta=meta or {}, spec=spec, retry_of=retry_of, conn=conn)
                if with_rows is not None:
                    with_rows(conn, job)
            future: Future[Any]
            try:
                if job_kind.runs_in == "thread":
                    future = self._threads.submit(self._run_thread, job.id, job_kind, spec)
                else:
                    future = self._pools[job_kind.pool].schedule(
                        run_in_process, args=(self.store.path, job.id, job_kind.run, spec)
                    )
            except Exception as exc:  # a job no worker will ever run must not stay queued
                self.repo.fail(job.id, self.public_error(f"the job could not be started: {type(exc).__name__}: {exc}"))
                raise
            self._futures[job.id] = future
        future.add_done_callback(functools.partial(self._settle, job.id))
        logger.info("job %s (%s) queued", job.id, kind)
        return job

    def get(self, job_id: str) -> Job:
        job = self.repo.get(job_id)
        if job is None:
            raise NotFoundError(f"no job with id {job_id!r}")
        return job

    def list(
        self, *, kind: str | None = None, state: JobState | None = None, limit: int = 100, **meta: Any
    ) -> builtins.list[Job]:
        """Jobs, newest first."""
        return self.repo.list(kind=kind, state=state, limit=limit, **meta)

    def find(self, **meta: Any) -> builtins.list[Job]:
        """Jobs whose ``meta`` holds all the given items, newest first."""
        return self.repo.list(**meta)

    def wait(self, job_id: str, timeout: float | None = None) -> Job:
        """Block until the job has finished or ``timeout`` [s] has passed; return its snapshot then."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            job = self.get(job_id)
            if job.finished or (deadline is not None and time.monotonic() >= deadline):
                return job
            time.sleep(POLL_INTERVAL)

    def cancel(self, job_id: str) -> Job:
        """Cancel a queued or running job: a process job's worker is terminated at once.

        Raises
        ------
        NotFoundError
            No such job.
        ConflictError
            The job has already finished (its state says how).
        """
        job = self.get(job_id)
        if not self.repo.cancel(job_id):
            raise ConflictError(
                f"job {job_id} has already finished (state {self.get(job_id).state.value}); nothing to cancel"
            )
        with self._lock:
            self._cancelled.add(job_id)
            future = self._futures.get(job_id)
        if future is not None:
            future.cancel()  # a queued job never starts; a running process job's worker is terminated
        logger.info("job %s (%s) cancelled while %s", job_id, job.kind, job.state.value)
        return self.get(job_id)

    def retry(self, job_id: str) -> Job:
        """Run a job that did not finish well (failed, interrupted, cancelled) again, as a new job.

        Raises
        ------
        ConflictError
            The job is still queued or running, or it is done.
        """
        job = self.get(job_id)
        if job.state in (JobState.queued, JobState.running, JobState.done):
            raise ConflictError(
                f"job {job_id} is {job.state.value}; only failed, interrupted or cancelled jobs can be retried"
            )
        if job.kind not in self._kinds:
            raise ConflictError(f"job {job_id} is of kind {job.kind!r}, which this service does not run")
        return self.submit(job.kind, job.spec, meta=job.meta, retry_of=job.id)

    def public_error(self, error: str) -> str:
        """A job's error as clients read it: the database's file and folder named, not shown (the log has them).

        The engine's store errors name the file they failed on (``pattern store /srv/data/patterns.sqlite3 ...``);
        where the service keeps its data is not the clients' business.
        """
        path = self.store.path
        for shown, said in ((str(path), "the service's database"), (str(path.parent), "the service's data folder")):
            if shown != path.anchor:  # never the root folder alone
                error = error.replace(shown, said)
        return error

    # -- internals ---------------------------------------------------------------------------

    def _run_thread(self, job_id: str, kind: JobKind, spec: dict[str, Any]) -> None:
        if job_id in self._cancelled or not self.repo.start(job_id):
            return
        logger.info("job %s running", job_id)

        def progress(fraction: float, stage: str | None = None) -> None:
            if job_id in self._cancelled:
                raise JobCancelled(job_id)
            self.repo.progress(job_id, fraction, stage)

        meta = kind.run(spec, progress) or {}
        if job_id in self._cancelled:
            return
        self.repo.finish(job_id, **meta)

    def _settle(self, job_id: str, future: Future[Any]) -> None:
        """Record how a job's future ended, unless the job already has its final state."""
        with self._lock:
            self._futures.pop(job_id, None)
            cancelled = job_id in self._cancelled
        try:
            future.result()
        except (CancelledError, JobCancelled):
            return
        except ProcessExpired as exc:
            if not cancelled:
                self.repo.fail(job_id, self.public_error(f"the worker process running the job died ({exc})"))
                logger.error("job %s: worker process died: %s", job_id, exc)
            return
        except Exception as exc:  # the job's failure is data, not a crash of the server
            error = str(exc) if isinstance(exc, JobError) else f"{type(exc).__name__}: {exc}"
            if self.repo.fail(job_id, self.public_error(error)):
                logger.warning("job %s failed: %s", job_id, error, exc_info=exc)
            return
        final = self.repo.get(job_id)
        logger.info("job %s ended (%s)", job_id, final.state.value if final else "deleted")
