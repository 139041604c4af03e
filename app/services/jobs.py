"""Job operations that touch what a job produces (the diagnosis a retried job now computes)."""

from __future__ import annotations

from app.db.diagnoses import DiagnosisRepository
from app.jobs import Job, JobManager
from app.services.diagnoses import DIAGNOSE_JOB
from engine.storage import PatternStore


def retry(store: PatternStore, jobs: JobManager, job_id: str) -> Job:
    """Run the job again (``ConflictError`` unless it failed, was interrupted or cancelled); a diagnosis follows the
    new job."""
    job = jobs.retry(job_id)
    if job.kind == DIAGNOSE_JOB and "diagnosis_id" in job.meta:
        DiagnosisRepository(store).set_job(job.meta["diagnosis_id"], job.id)
    return job
