"""Job operations that touch what a job produces (the diagnosis a retried job now computes)."""

from __future__ import annotations

import sqlite3

from app.db.diagnoses import DiagnosisRepository
from app.jobs import Job, JobManager, Retried
from app.services.diagnoses import DIAGNOSE_JOB
from engine.storage import PatternStore


def retry(store: PatternStore, jobs: JobManager, job_id: str) -> Retried:
    """Run the job again, idempotently (:meth:`JobManager.retry`); a diagnosis follows the new job.

    ``ConflictError`` unless the job failed, was interrupted or cancelled. A retry of it that is already queued,
    running or done is returned instead of a new one (``created`` False). The diagnosis follows the new job in the
    transaction that adds it.
    """

    def follow(conn: sqlite3.Connection, job: Job) -> None:
        if job.kind == DIAGNOSE_JOB and "diagnosis_id" in job.meta:
            DiagnosisRepository(store).set_job(job.meta["diagnosis_id"], job.id, conn)

    return jobs.retry(job_id, with_rows=follow)
