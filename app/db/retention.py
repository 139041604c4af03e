"""Deleting across the service's tables: which row may go, one job at a time or every old row of a retention run.

What refers to what (the only links between the service's tables):

* ``diagnoses.job_id`` -> ``jobs.id``: while a diagnosis has no result, its state is its job's, and a retry
  needs that job (its spec). Once it has a result it reads ``done`` without its job
  (:func:`app.services.diagnoses.job_state`), so the link is needed no longer.
* ``diagnoses.record_id`` -> ``records.id`` and ``jobs.meta.record_id`` -> ``records.id``: a diagnosis job, and
  its retry, read the record as it was sent.
* ``jobs.retry_of`` -> ``jobs.id``: a retry names the job it runs again.
* ``figures.owner_id`` -> ``diagnoses.id``: a diagnosis's figures are part of it and go with it.

Identifications and pattern sets are needed by no other row.

**The rule**: a row is deleted only when no other row needs it (the links above, with the exception that a
diagnosis's result frees its job), and never while work on it is queued or running. So a job goes only once it
has finished, when no result-less diagnosis follows it and no later job re-runs it (the retry goes first); a
diagnosis goes with its figures once its job has finished (an explicit ``DELETE /v1/diagnoses/{id}`` cancels a
running job first, :func:`app.services.diagnoses.delete`); a record goes only when no diagnosis and no job names
it. (``DELETE /v1/records/{id}`` is a person's explicit choice and is the one exception: its diagnoses keep their
results.) Pattern sets are never deleted by age.

Timestamps are compared as the stored ISO 8601 UTC text (:func:`app.db.codec.to_text`, one format, so text order
is time order).
"""

from __future__ import annotations

import sqlite3
from dataclasses import dataclass, field
from datetime import datetime
from typing import Literal

from app.db.codec import to_text
from app.db.jobs import FINISHED, UNFINISHED, JobState
from engine.storage import PatternStore

__all__ = ["JobDeletion", "Pruned", "RetentionRepository"]


def _in(states: frozenset[JobState]) -> str:
    return ", ".join(f"'{s.value}'" for s in sorted(states))


_FINISHED = _in(FINISHED)
_UNFINISHED = _in(UNFINISHED)

#: Jobs some other row still needs (see the module docstring): followed by a diagnosis without a result, or re-run
#: by a later job.
_NEEDED_JOBS = (
    "SELECT job_id FROM diagnoses WHERE result_z IS NULL AND job_id IS NOT NULL "
    "UNION SELECT retry_of FROM jobs WHERE retry_of IS NOT NULL"
)
#: Records some diagnosis or job names.
_NEEDED_RECORDS = (
    "SELECT record_id FROM diagnoses WHERE record_id IS NOT NULL "
    "UNION SELECT json_extract(meta, '$.record_id') FROM jobs WHERE json_extract(meta, '$.record_id') IS NOT NULL"
)


@dataclass(frozen=True)
class JobDeletion:
    """The outcome of :meth:`RetentionRepository.delete_job`.

    Attributes
    ----------
    outcome : {"deleted", "missing", "unfinished", "followed", "retried"}
        Deleted; no such job; still queued or running (``state``); a diagnosis without a result follows it
        (``other`` is the diagnosis's id); a later job re-runs it (``other`` is that job's id).
    """

    outcome: Literal["deleted", "missing", "unfinished", "followed", "retried"]
    state: str | None = None
    other: str | None = None


@dataclass
class Pruned:
    """Rows one retention run deleted, by table (figures with their diagnoses)."""

    jobs: int = 0
    diagnoses: int = 0
    figures: int = 0
    records: int = 0
    identifications: int = 0
    ids: dict[str, list[str]] = field(default_factory=dict)

    def counts(self) -> dict[str, int]:
        """Rows deleted per table."""
        return {
            "jobs": self.jobs,
            "diagnoses": self.diagnoses,
            "figures": self.figures,
            "records": self.records,
            "identifications": self.identifications,
        }


class RetentionRepository:
    """Deletions that follow the module's rule, in the store's SQLite file.

    Parameters
    ----------
    store : PatternStore
        The service's file.
    """

    def __init__(self, store: PatternStore) -> None:
        self.store = store

    def delete_job(self, job_id: str) -> JobDeletion:
        """Delete one finished job that no other row needs (checked and deleted in one write transaction)."""
        with self.store.writing() as conn:
            row = conn.execute("SELECT state FROM jobs WHERE id = ?", (job_id,)).fetchone()
            if row is None:
                return JobDeletion("missing")
            state = str(row[0])
            if state not in {s.value for s in FINISHED}:
                return JobDeletion("unfinished", state=state)
            follower = conn.execute(
                "SELECT id FROM diagnoses WHERE job_id = ? AND result_z IS NULL ORDER BY seq LIMIT 1", (job_id,)
            ).fetchone()
            if follower is not None:
                return JobDeletion("followed", state=state, other=follower[0])
            retry = conn.execute("SELECT id FROM jobs WHERE retry_of = ? ORDER BY seq LIMIT 1", (job_id,)).fetchone()
            if retry is not None:
                return JobDeletion("retried", state=state, other=retry[0])
            conn.execute("DELETE FROM jobs WHERE id = ?", (job_id,))
        return JobDeletion("deleted", state=state)

    def prune(self, cutoff: datetime) -> Pruned:
        """Delete what was stored (a job: finished) before ``cutoff`` and no other row needs.

        In this order, one write transaction each, so that what an earlier step frees a later one may take:
        diagnoses whose job has finished (or is gone), with their figures; finished jobs (repeated until no more
        go, so that a chain of retries goes newest first); records no diagnosis or job names; identifications.

        Parameters
        ----------
        cutoff : datetime
            Timezone-aware; rows stored (jobs: finished) at or after it stay.

        Returns
        -------
        Pruned
            How many rows went from each table, and the ids of the deleted jobs, diagnoses, records and
            identifications (``ids``).
        """
        before = str(to_text(cutoff))
        out = Pruned()
        with self.store.writing() as conn:
            ids = self._ids(
                conn,
                "SELECT id FROM diagnoses WHERE created_at < ? "
                f"AND job_id NOT IN (SELECT id FROM jobs WHERE state IN ({_UNFINISHED}))",
                (before,),
            )
            for chunk in _chunks(ids):
                marks = ", ".join("?" * len(chunk))
                out.figures += conn.execute(f"DELETE FROM figures WHERE owner_id IN ({marks})", chunk).rowcount
                out.diagnoses += conn.execute(f"DELETE FROM diagnoses WHERE id IN ({marks})", chunk).rowcount
            out.ids["diagnoses"] = ids
            # figures whose diagnosis is gone (none should be; they are nobody's)
            out.figures += conn.execute("DELETE FROM figures WHERE owner_id NOT IN (SELECT id FROM diagnoses)").rowcount
        out.ids["jobs"] = []
        with self.store.writing() as conn:
            while True:
                ids = self._ids(
                    conn,
                    f"SELECT id FROM jobs WHERE state IN ({_FINISHED}) AND coalesce(finished_at, created_at) < ? "
                    f"AND id NOT IN ({_NEEDED_JOBS})",
                    (before,),
                )
                if not ids:
                    break
                for chunk in _chunks(ids):
                    out.jobs += conn.execute(
                        f"DELETE FROM jobs WHERE id IN ({', '.join('?' * len(chunk))})", chunk
                    ).rowcount
                out.ids["jobs"] += ids
        with self.store.writing() as conn:
            ids = self._ids(
                conn, f"SELECT id FROM records WHERE created_at < ? AND id NOT IN ({_NEEDED_RECORDS})", (before,)
            )
            for chunk in _chunks(ids):
                out.records += conn.execute(
                    f"DELETE FROM records WHERE id IN ({', '.join('?' * len(chunk))})", chunk
                ).rowcount
            out.ids["records"] = ids
        with self.store.writing() as conn:
            ids = self._ids(conn, "SELECT id FROM identifications WHERE created_at < ?", (before,))
            for chunk in _chunks(ids):
                out.identifications += conn.execute(
                    f"DELETE FROM identifications WHERE id IN ({', '.join('?' * len(chunk))})", chunk
                ).rowcount
            out.ids["identifications"] = ids
        return out

    @staticmethod
    def _ids(conn: sqlite3.Connection, sql: str, args: tuple[str, ...]) -> list[str]:
        return [str(r[0]) for r in conn.execute(sql, args)]


def _chunks(ids: list[str], size: int = 500) -> list[list[str]]:
    """``ids`` in lists of at most ``size`` (SQLite's bound on a statement's parameters is 32766)."""
    return [ids[i : i + size] for i in range(0, len(ids), size)]
