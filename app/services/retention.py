"""Retention: deleting finished jobs and identifications on request, deleting old rows by age, compacting the file.

* :func:`delete_job` and :func:`delete_identification` delete one row on a client's request
  (``DELETE /v1/jobs/{id}``, ``DELETE /v1/identifications/{id}``), following the rule of
  :mod:`app.db.retention`: a row goes only when no other row needs it, and a job only once it has finished
  (a queued or running one must be cancelled first, ``POST /v1/jobs/{id}/cancel``).
* :func:`run` is one retention run: with ``BACKLASH_RETENTION_DAYS`` set, the finished jobs, diagnoses (with
  their figures), identifications and no longer referenced records stored more than that many days ago are
  deleted (:meth:`app.db.retention.RetentionRepository.prune`); then the file is compacted
  (:meth:`engine.storage.PatternStore.compact`), which gives the pages freed by these deletions, and by every
  ``DELETE`` since the last run, back to the file system. Without the setting a run deletes nothing and only
  compacts: by default no data is lost.
* :class:`RetentionScheduler` runs :func:`run` in a thread of the service when it starts and then every
  ``BACKLASH_RETENTION_INTERVAL_HOURS``; ``POST /v1/maintenance/retention`` and ``backlash store prune`` run one
  on demand. Runs of one process never overlap (a lock); a command-line run beside the service is safe too, as
  SQLite serialises the writes (the service's writes wait while a compaction holds the write lock).

Pattern sets are never deleted by age: a trained identifier is the service's knowledge, not its history.
Their number is bounded instead (``BACKLASH_MAX_PATTERN_SETS``, :func:`app.services.patterns.pattern_set_room`).
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import Any

from app.db.codec import now
from app.db.identifications import IdentificationRepository
from app.db.retention import Pruned, RetentionRepository
from app.services.errors import ConflictError, NotFoundError
from engine.storage import Compaction, PatternStore

logger = logging.getLogger(__name__)

__all__ = ["RetentionReport", "RetentionScheduler", "delete_identification", "delete_job", "run"]

#: Seconds in a day and in an hour.
DAY_S, HOUR_S = 86_400.0, 3_600.0


def delete_job(store: PatternStore, job_id: str) -> None:
    """Delete a finished job that no other row needs (:mod:`app.db.retention`).

    Raises
    ------
    NotFoundError
        No such job (404).
    ConflictError
        The job is queued or running (cancel it first), a diagnosis without a result follows it (delete the
        diagnosis first, or retry the job), or a later job re-runs it (delete that one first): 409, saying which.
    """
    done = RetentionRepository(store).delete_job(job_id)
    if done.outcome == "missing":
        raise NotFoundError(f"no job with id {job_id!r}; GET /v1/jobs lists them")
    if done.outcome == "unfinished":
        raise ConflictError(
            f"job {job_id} is {done.state}: only a finished job can be deleted; cancel it first "
            f"(POST /v1/jobs/{job_id}/cancel), then delete it"
        )
    if done.outcome == "followed":
        raise ConflictError(
            f"job {job_id} ({done.state}) is the job of diagnosis {done.other}, which has no result: delete the "
            f"diagnosis first (DELETE /v1/diagnoses/{done.other}), or retry the job (POST /v1/jobs/{job_id}/retry)"
        )
    if done.outcome == "retried":
        raise ConflictError(
            f"job {job_id} ({done.state}) is re-run by job {done.other} (its retry_of): delete that job first"
        )
    logger.info("deleted job %s (%s)", job_id, done.state)


def delete_identification(store: PatternStore, identification_id: str) -> None:
    """Delete a stored identification (it leaves its asset's history and trend); nothing else needs one.

    Raises
    ------
    NotFoundError
        No such identification (404).
    """
    if not IdentificationRepository(store).delete(identification_id):
        raise NotFoundError(
            f"no identification with id {identification_id!r}; GET /v1/assets/{{asset}}/history lists an "
            "asset's identifications"
        )
    logger.info("deleted identification %s", identification_id)


@dataclass(frozen=True)
class RetentionReport:
    """What one retention run did.

    Attributes
    ----------
    retention_days : float or None
        The age limit it applied [days]; ``None``: nothing is deleted by age.
    cutoff : datetime or None
        Rows stored (jobs: finished) before this instant were candidates for deletion.
    deleted : dict of str to int
        Rows deleted per table (``jobs``, ``diagnoses``, ``figures``, ``records``, ``identifications``).
    compaction : Compaction or None
        The compaction (``None`` when the run was asked not to compact).
    bytes_before, bytes_after : int
        Size of the database file plus its ``-wal`` file before the deletions and after the compaction [bytes].
    seconds : float
        Duration of the run [s].
    """

    retention_days: float | None
    cutoff: datetime | None
    deleted: dict[str, int]
    compaction: Compaction | None
    bytes_before: int
    bytes_after: int
    seconds: float
    ids: dict[str, list[str]] = field(default_factory=dict, repr=False)

    def to_dict(self) -> dict[str, Any]:
        """The report as JSON-able data (the API's and the CLI's answer); the deleted ids are left out."""
        return {
            "retention_days": self.retention_days,
            "cutoff": self.cutoff.isoformat() if self.cutoff else None,
            "deleted": dict(self.deleted),
            "compaction": None if self.compaction is None else self.compaction.method,
            "free_pages_before": None if self.compaction is None else self.compaction.free_pages_before,
            "bytes_before": self.bytes_before,
            "bytes_after": self.bytes_after,
            "bytes_freed": self.bytes_before - self.bytes_after,
            "seconds": round(self.seconds, 3),
        }


def run(
    store: PatternStore, retention_days: float | None, *, compact: bool = True, at: datetime | None = None
) -> RetentionReport:
    """One retention run: delete what is older than ``retention_days`` (if set), then compact the file.

    Parameters
    ----------
    store : PatternStore
        The service's file.
    retention_days : float or None
        Age limit [days]; ``None`` or 0 deletes nothing (only the compaction runs).
    compact : bool
        Compact the file afterwards (:meth:`engine.storage.PatternStore.compact`).
    at : datetime, optional
        The run's "now" (timezone-aware; default the current instant): the cutoff is ``at - retention_days``.

    Returns
    -------
    RetentionReport
        Counts of deleted rows and the file's size before and after [bytes]; also logged.
    """
    started = time.monotonic()
    bytes_before = store.size_bytes()
    days = retention_days or None
    cutoff = None if days is None else (at or now()) - timedelta(days=days)
    pruned = Pruned() if cutoff is None else RetentionRepository(store).prune(cutoff)
    compaction = store.compact() if compact else None
    report = RetentionReport(
        retention_days=days,
        cutoff=cutoff,
        deleted=pruned.counts(),
        compaction=compaction,
        bytes_before=bytes_before,
        bytes_after=store.size_bytes(),
        seconds=time.monotonic() - started,
        ids=pruned.ids,
    )
    counts = ", ".join(f"{n} {table}" for table, n in report.deleted.items())
    logger.info(
        "retention run on %s: %s; deleted %s; compaction %s; %d -> %d bytes in %.2f s",
        store.path,
        "keeping everything (BACKLASH_RETENTION_DAYS unset)"
        if days is None
        else f"older than {days:g} days (before {cutoff.isoformat() if cutoff else '-'})",
        counts,
        report.to_dict()["compaction"],
        report.bytes_before,
        report.bytes_after,
        report.seconds,
    )
    if any(pruned.ids.values()):
        logger.debug("retention run deleted ids: %s", pruned.ids)
    return report


class RetentionScheduler:
    """Retention runs of the service: one when it starts, then one every ``interval_hours``; and on demand.

    Parameters
    ----------
    store : PatternStore
        The service's file.
    retention_days : float or None
        ``BACKLASH_RETENTION_DAYS`` [days]; ``None``: nothing is deleted by age (runs only compact).
    interval_hours : float
        ``BACKLASH_RETENTION_INTERVAL_HOURS`` [h]; 0: no periodic run (:meth:`run_now` still runs one).
    """

    def __init__(self, store: PatternStore, retention_days: float | None, interval_hours: float) -> None:
        self.store = store
        self.retention_days = retention_days or None
        self.interval_s = float(interval_hours) * HOUR_S
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.last: RetentionReport | None = None

    def start(self) -> None:
        """Start the periodic runs in a daemon thread (nothing when the interval is 0)."""
        if self.interval_s <= 0 or self._thread is not None:
            return
        self._thread = threading.Thread(target=self._loop, name="backlash-retention", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 30.0) -> None:
        """Stop the periodic runs; a run under way finishes first (waited for up to ``timeout`` [s])."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)
            if self._thread.is_alive():
                logger.warning("the retention run did not finish within %g s of the shutdown", timeout)

    def run_now(self, *, compact: bool = True) -> RetentionReport:
        """One retention run now (after any run under way: runs never overlap)."""
        with self._lock:
            self.last = run(self.store, self.retention_days, compact=compact)
            return self.last

    def _loop(self) -> None:
        delay = 0.0  # the first run when the service starts
        while not self._stop.wait(delay):
            try:
                self.run_now()
            except Exception:  # a failed run (a locked or full disk) must not end the service's runs
                logger.exception("retention run on %s failed; the next one is in %g h", self.store.path,
                                 self.interval_s / HOUR_S)  # fmt: skip
            delay = self.interval_s
