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
progress the same way for both places. A runner that produces stored rows (a pattern set, a
diagnosis's result) returns them as a :class:`JobResult`: they are written in the same transaction
that moves the job to ``done`` (:func:`finish_job`), so a process killed at any moment leaves both
or neither, and a cancelled job stores nothing.

A retry (:meth:`JobManager.retry`) is idempotent: it re-runs the newest job of the retry chain, at
most one retry of a job is ever queued or running, and asking again returns that retry instead of
running the work twice; a job whose result is already stored is not run again (its retry is
``done`` at once). When the service starts, jobs that were queued or
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
    "JobResult",
    "ProgressFn",
    "Retried",
    "RowsFn",
    "StoredFn",
    "die_with_parent",
    "finish_job",
    "new_process_pool",
    "run_in_process",
]

ProgressFn = Callable[[float, str], None]
#: ``with_rows(conn, job)`` of :meth:`JobManager.submit`: writes the rows that belong with a new job, in its transaction.
RowsFn = Callable[[sqlite3.Connection, Job], None]
#: ``stored(conn, spec)`` of a :class:`JobKind`: the meta of a spec whose result is already stored, else None.
StoredFn = Callable[[sqlite3.Connection, dict[str, Any]], dict[str, Any] | None]


@dataclass(frozen=True)
class JobResult:
    """What a runner returns when its job stores rows: written with the job's move to ``done``, in one transaction.

    Attributes
    ----------
    meta : dict
        Items merged into the job's meta.
    write : callable or None
        ``write(conn)`` writes the job's result in the write transaction ``conn`` (not committed by it). If it
        raises, or the job is no longer ``running`` (cancelled, interrupted), nothing of it is stored.
    """

    meta: dict[str, Any]
    write: Callable[[sqlite3.Connection], None] | None = None


#: What a runner returns: items merged into the job's meta, a :class:`JobResult`, or None.
RunnerResult = dict[str, Any] | JobResult | None
#: ``run(spec, progress)`` of a thread kind.
ThreadRunner = Callable[[dict[str, Any], ProgressFn], RunnerResult]
#: ``run(db_path, spec, progress)`` of a process kind: a module-level function (it is pickled by name).
ProcessRunner = Callable[[Path, dict[str, Any], ProgressFn], RunnerResult]
#: Stage of a retry that found its job's result already stored (it is ``done`` at once, nothing is run).
ALREADY_STORED = "done: the result was already stored"

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
    stored : callable or None
        :data:`StoredFn`: whether a spec's result is already stored (a retry then does not run it again).
    """

    name: str
    runs_in: Literal["thread", "process"]
    run: Callable[..., RunnerResult]
    pool: str = "default"
    stored: StoredFn | None = None


@dataclass(frozen=True)
class Retried:
    """The answer of :meth:`JobManager.retry`: the job that carries the work on, and whether the call queued it.

    Attributes
    ----------
    job : Job
        The new retry, or the retry that was already queued, running or done.
    created : bool
        True if this call created ``job`` (queued, or done at once when the result was already stored); False if
        an earlier retry is returned.
    """

    job: Job
    created: bool


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


def finish_job(jobs: JobRepository, job_id: str, result: RunnerResult) -> bool:
    """Store a runner's ``result`` and move its job ``running`` -> ``done`` in one write transaction.

    The result's rows are written first, then the job moves; a process killed between the two commits
    neither. If the job is no longer ``running`` (a client cancelled it, a restart interrupted it), the
    transaction is rolled back: nothing of the result is stored.

    Returns
    -------
    bool
        Whether the job is now ``done`` with its result.
    """
    if isinstance(result, JobResult):
        meta, write = result.meta, result.write
    else:
        meta, write = result or {}, None
    try:
        with jobs.store.writing() as conn:
            if write is not None:
                write(conn)
            if not jobs.finish(job_id, conn=conn, **meta):
                raise _NotRunning(job_id)
    except _NotRunning:
        logger.info("job %s is no longer running; its result is dropped", job_id)
        return False
    return True


class _NotRunning(Exception):
    """Rolls back :func:`finish_job`'s transaction when the job has left ``running``."""


def run_in_process(db_path: Path, job_id: str, run: ProcessRunner, spec: dict[str, Any]) -> None:
    """Entry point of a job in a worker process: mark it running, run it, store its result and ``done`` together
    (:func:`finish_job`; or raise)."""
    jobs = JobRepository(PatternStore(db_path))
    if not jobs.start(job_id):
        return  # cancelled (or interrupted) before it started

    def progress(fraction: float, stage: str | None = None) -> None:
        jobs.progress(job_id, fraction, stage)

    try:
        result = run(db_path, spec, progress)
        finish_job(jobs, job_id, result)
    except Exception as exc:  # sent back as text: not every exception survives pickling
        raise JobError(f"{type(exc).__name__}: {exc}") from None


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
                self._check_room(conn)
                job = self.repo.create(kind, meta=meta or {}, spec=spec, retry_of=retry_of, conn=conn)
                if with_rows is not None:
                    with_rows(conn, job)
            future = self._schedule(job, job_kind)
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

    def retry(self, job_id: str, *, with_rows: RowsFn | None = None) -> Retried:
        """Run a job that did not finish well (failed, interrupted, cancelled) again, as a new job; idempotent.

        The retry re-runs the newest job of the retry chain (``retry_of`` names it), so that a job has at
        most one retry and at most one of the chain is ever queued or running. In one write transaction:

        * if a retry of the job (or of its retries) is queued, running or done, that one is returned
          (``created`` False) and nothing is run: retrying twice runs the work once;
        * else, if the kind's ``stored`` finds the result already stored (e.g. a crash after the result
          was written), the new job is ``done`` at once (stage :data:`ALREADY_STORED`) and nothing is run;
        * else a new job is queued (within the queue's limit) and ``with_rows(conn, job)`` runs in that
          transaction (a diagnosis then follows the new job).

        Raises
        ------
        NotFoundError
            No such job.
        ConflictError
            The job itself is queued, running or done (nothing to retry), or of a kind this service does not run.
        QueueFullError
            A new job is needed and too many jobs are queued or running, or the service is shutting down.
        """
        job = self.get(job_id)
        if job.state in (JobState.queued, JobState.running, JobState.done):
            raise ConflictError(
                f"job {job_id} is {job.state.value}; only failed, interrupted or cancelled jobs can be retried"
            )
        job_kind = self._kinds.get(job.kind)
        if job_kind is None:
            raise ConflictError(f"job {job_id} is of kind {job.kind!r}, which this service does not run")
        with self._lock:
            if self._closed:
                raise QueueFullError("the server is shutting down and accepts no new jobs")
            with self.store.writing() as conn:
                latest = self.repo.latest_retry(job_id, conn)
                if latest is not None and latest.state in (JobState.queued, JobState.running, JobState.done):
                    logger.info("job %s: its retry %s is %s; not run again", job_id, latest.id, latest.state.value)
                    return Retried(latest, created=False)
                target = latest or job
                stored = job_kind.stored(conn, target.spec) if job_kind.stored is not None else None
                if stored is None:
                    self._check_room(conn)
                new = self.repo.create(
                    target.kind,
                    meta={**target.meta, **(stored or {})},
                    spec=target.spec,
                    retry_of=target.id,
                    conn=conn,
                    done=None if stored is None else ALREADY_STORED,
                )
                if with_rows is not None:
                    with_rows(conn, new)
            if stored is not None:
                logger.info(
                    "job %s: the result of %s was already stored; its retry %s is done", job_id, target.id, new.id
                )
                return Retried(new, created=True)
            future = self._schedule(new, job_kind)
        future.add_done_callback(functools.partial(self._settle, new.id))
        logger.info("job %s (%s) queued, a retry of %s", new.id, new.kind, target.id)
        return Retried(new, created=True)

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

    def _check_room(self, conn: sqlite3.Connection) -> None:
        """Raise :class:`QueueFullError` if the queue is full (read in the write transaction that adds a job)."""
        pending = self.repo.count_unfinished(conn)
        if pending >= self._max_pending:
            raise QueueFullError(
                f"{pending} jobs are queued or running (the limit is {self._max_pending}); "
                "wait for some to finish and retry"
            )

    def _schedule(self, job: Job, job_kind: JobKind) -> Future[Any]:
        """Hand a stored, queued job to its thread pool or process pool (under ``self._lock``); its future."""
        future: Future[Any]
        try:
            if job_kind.runs_in == "thread":
                future = self._threads.submit(self._run_thread, job.id, job_kind, job.spec)
            else:
                future = self._pools[job_kind.pool].schedule(
                    run_in_process, args=(self.store.path, job.id, job_kind.run, job.spec)
                )
        except Exception as exc:  # a job no worker will ever run must not stay queued
            self.repo.fail(job.id, self.public_error(f"the job could not be started: {type(exc).__name__}: {exc}"))
            raise
        self._futures[job.id] = future
        return future

    def _run_thread(self, job_id: str, kind: JobKind, spec: dict[str, Any]) -> None:
        if job_id in self._cancelled or not self.repo.start(job_id):
            return
        logger.info("job %s running", job_id)

        def progress(fraction: float, stage: str | None = None) -> None:
            if job_id in self._cancelled:
                raise JobCancelled(job_id)
            self.repo.progress(job_id, fraction, stage)

        result = kind.run(spec, progress)
        if job_id in self._cancelled:
            return
        finish_job(self.repo, job_id, result)

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
