"""The ``jobs`` table: every background job's state, progress, error and what it needs to run again.

States: ``queued`` -> ``running`` -> ``done`` | ``failed`` | ``cancelled``; a job that was queued or
running when its service stopped becomes ``interrupted`` when the service starts again
(:meth:`JobRepository.interrupt_unfinished`). Every transition is a conditional ``UPDATE`` (only
from the states it may come from), so a process that finishes a job cannot overwrite a
cancellation, and the other way round.
"""

from __future__ import annotations

import builtins
import contextlib
import json
import sqlite3
import uuid
from dataclasses import dataclass
from datetime import datetime
from enum import StrEnum
from typing import Any

from app.db.codec import from_text, now, to_text
from engine.storage import PatternStore

__all__ = ["FINISHED", "UNFINISHED", "Job", "JobRepository", "JobState"]


class JobState(StrEnum):
    queued = "queued"
    running = "running"
    done = "done"
    failed = "failed"
    interrupted = "interrupted"
    cancelled = "cancelled"


#: States a job leaves only by a retry (which makes a new job).
FINISHED: frozenset[JobState] = frozenset({JobState.done, JobState.failed, JobState.interrupted, JobState.cancelled})
#: States of a job that still has work to do.
UNFINISHED: frozenset[JobState] = frozenset({JobState.queued, JobState.running})

_COLUMNS = "id, kind, state, progress, stage, error, created_at, started_at, finished_at, meta, spec, retry_of"


@dataclass(frozen=True)
class Job:
    """Snapshot of one job as stored (they do not change; read again for news).

    Attributes
    ----------
    meta : dict
        What the job produces, by name (``pattern_set_id``, ``diagnosis_id``), for lookups and answers.
    spec : dict
        Everything needed to run the job again (its kind's runner reads it); JSON.
    retry_of : str or None
        The job this one re-runs.
    """

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
    spec: dict[str, Any]
    retry_of: str | None = None

    @property
    def finished(self) -> bool:
        return self.state in FINISHED


def _row(row: tuple[Any, ...]) -> Job:
    created = from_text(row[6])
    assert created is not None  # NOT NULL column
    return Job(
        id=row[0],
        kind=row[1],
        state=JobState(row[2]),
        progress=float(row[3]),
        stage=row[4],
        error=row[5],
        created_at=created,
        started_at=from_text(row[7]),
        finished_at=from_text(row[8]),
        meta=json.loads(row[9]),
        spec=json.loads(row[10]),
        retry_of=row[11],
    )


def _states(states: frozenset[JobState] | tuple[JobState, ...]) -> str:
    return ", ".join(f"'{s.value}'" for s in sorted(states))


class JobRepository:
    """Jobs in the store's SQLite file.

    Parameters
    ----------
    store : PatternStore
        The file (opening it creates or migrates the tables).
    """

    def __init__(self, store: PatternStore) -> None:
        self.store = store

    def create(
        self,
        kind: str,
        *,
        meta: dict[str, Any],
        spec: dict[str, Any],
        retry_of: str | None = None,
        conn: sqlite3.Connection | None = None,
        done: str | None = None,
    ) -> Job:
        """Insert a new ``queued`` job and return it (in the write transaction ``conn`` when given).

        ``done``: insert it ``done`` at once, with this stage (a retry whose result is already stored).
        """
        created = now()
        job = Job(
            id=uuid.uuid4().hex,
            kind=kind,
            state=JobState.queued if done is None else JobState.done,
            progress=0.0 if done is None else 1.0,
            stage="queued" if done is None else done,
            error=None,
            created_at=created,
            started_at=None if done is None else created,
            finished_at=None if done is None else created,
            meta=dict(meta),
            spec=dict(spec),
            retry_of=retry_of,
        )
        with self.store.writing() if conn is None else contextlib.nullcontext(conn) as conn:
            conn.execute(
                f"INSERT INTO jobs ({_COLUMNS}) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    job.id,
                    job.kind,
                    job.state.value,
                    job.progress,
                    job.stage,
                    None,
                    to_text(job.created_at),
                    to_text(job.started_at),
                    to_text(job.finished_at),
                    json.dumps(job.meta),
                    json.dumps(job.spec, allow_nan=False),
                    retry_of,
                ),
            )
        return job

    def get(self, job_id: str, conn: sqlite3.Connection | None = None) -> Job | None:
        """The job, or None (read in ``conn`` when given)."""
        with self.store.reading() if conn is None else contextlib.nullcontext(conn) as conn:
            row = conn.execute(f"SELECT {_COLUMNS} FROM jobs WHERE id = ?", (job_id,)).fetchone()
        return None if row is None else _row(row)

    def latest_retry(self, job_id: str, conn: sqlite3.Connection | None = None) -> Job | None:
        """The newest job that re-runs ``job_id``, directly or through retries of its retries; None if none does.

        A retry re-runs the newest job of its chain (:meth:`app.jobs.JobManager.retry`), so the chain is a line
        and its newest job carries the work on (read in ``conn`` when given).
        """
        with self.store.reading() if conn is None else contextlib.nullcontext(conn) as conn:
            row = conn.execute(
                "WITH RECURSIVE chain(id) AS (SELECT id FROM jobs WHERE retry_of = ? "
                "UNION SELECT jobs.id FROM jobs JOIN chain ON jobs.retry_of = chain.id) "
                f"SELECT {_COLUMNS} FROM jobs WHERE id IN (SELECT id FROM chain) ORDER BY seq DESC LIMIT 1",
                (job_id,),
            ).fetchone()
        return None if row is None else _row(row)

    def list(
        self, *, kind: str | None = None, state: JobState | None = None, limit: int = 100, **meta: Any
    ) -> builtins.list[Job]:
        """Jobs, newest first, optionally of one kind/state and whose ``meta`` holds the given items."""
        where, args = [], []
        if kind is not None:
            where.append("kind = ?")
            args.append(kind)
        if state is not None:
            where.append("state = ?")
            args.append(state.value)
        for key, value in meta.items():
            where.append("json_extract(meta, ?) = ?")
            args.extend([f"$.{key}", value])
        sql = f"SELECT {_COLUMNS} FROM jobs" + (" WHERE " + " AND ".join(where) if where else "")
        with self.store.reading() as conn:
            rows = conn.execute(sql + " ORDER BY seq DESC LIMIT ?", (*args, int(limit))).fetchall()
        return [_row(r) for r in rows]

    def count_unfinished(self, conn: sqlite3.Connection | None = None) -> int:
        """Queued plus running jobs (read in ``conn`` when given, e.g. the transaction that adds one)."""
        with self.store.reading() if conn is None else contextlib.nullcontext(conn) as conn:
            return int(conn.execute(f"SELECT count(*) FROM jobs WHERE state IN ({_states(UNFINISHED)})").fetchone()[0])

    # -- transitions (each only from the states it may come from; True if it happened) -------------

    def start(self, job_id: str, stage: str = "starting") -> bool:
        return self._move(job_id, (JobState.queued,), state=JobState.running, started_at=to_text(now()), stage=stage)

    def progress(self, job_id: str, fraction: float, stage: str | None) -> bool:
        """Raise the progress to ``fraction`` (clamped to 0..1, never lowered) and set the stage."""
        value = min(1.0, max(0.0, float(fraction)))
        with self.store.writing() as conn:
            cur = conn.execute(
                "UPDATE jobs SET progress = max(progress, ?), stage = coalesce(?, stage) WHERE id = ? AND state = ?",
                (value, stage, job_id, JobState.running.value),
            )
            return cur.rowcount == 1

    def finish(self, job_id: str, *, conn: sqlite3.Connection | None = None, **meta: Any) -> bool:
        """``running`` -> ``done`` (progress 1), merging ``meta`` into the job's (in the write transaction ``conn``
        when given: the one that stores the job's result, :func:`app.jobs.manager.finish_job`)."""
        with self.store.writing() if conn is None else contextlib.nullcontext(conn) as conn:
            row = conn.execute("SELECT meta FROM jobs WHERE id = ?", (job_id,)).fetchone()
            merged = {**(json.loads(row[0]) if row else {}), **meta}
            cur = conn.execute(
                "UPDATE jobs SET state = ?, progress = 1.0, stage = 'done', finished_at = ?, meta = ? "
                "WHERE id = ? AND state = ?",
                (JobState.done.value, to_text(now()), json.dumps(merged), job_id, JobState.running.value),
            )
            return cur.rowcount == 1

    def fail(self, job_id: str, error: str) -> bool:
        return self._move(
            job_id, tuple(UNFINISHED), state=JobState.failed, error=error, finished_at=to_text(now()), stage="failed"
        )

    def cancel(self, job_id: str) -> bool:
        return self._move(
            job_id,
            tuple(UNFINISHED),
            state=JobState.cancelled,
            error="cancelled by a client",
            finished_at=to_text(now()),
            stage="cancelled",
        )

    def interrupt_unfinished(self, reason: str) -> builtins.list[str]:
        """Every queued or running job becomes ``interrupted`` with ``reason``; return their ids."""
        with self.store.writing() as conn:
            ids = [r[0] for r in conn.execute(f"SELECT id FROM jobs WHERE state IN ({_states(UNFINISHED)})")]
            conn.execute(
                f"UPDATE jobs SET state = ?, error = ?, finished_at = ?, stage = 'interrupted' "
                f"WHERE state IN ({_states(UNFINISHED)})",
                (JobState.interrupted.value, reason, to_text(now())),
            )
        return ids

    def delete(self, job_id: str) -> None:
        with self.store.writing() as conn:
            conn.execute("DELETE FROM jobs WHERE id = ?", (job_id,))

    def _move(self, job_id: str, sources: tuple[JobState, ...], *, state: JobState, **columns: Any) -> bool:
        assignments = ", ".join(f"{k} = ?" for k in columns)
        with self.store.writing() as conn:
            cur = conn.execute(
                f"UPDATE jobs SET state = ?, {assignments} WHERE id = ? AND state IN ({_states(sources)})",
                (state.value, *columns.values(), job_id),
            )
            return cur.rowcount == 1
