"""GET /v1/jobs/{job_id}: state and progress of a background job."""

from __future__ import annotations

from fastapi import APIRouter

from app.api.deps import JobsDep
from app.jobs import Job
from app.schemas.common import ErrorPublic
from app.schemas.jobs import JobPublic

router = APIRouter(prefix="/jobs", tags=["jobs"])


def job_public(job: Job) -> JobPublic:
    return JobPublic(
        id=job.id,
        kind=job.kind,
        state=job.state.value,
        progress=job.progress,
        stage=job.stage,
        error=job.error,
        created_at=job.created_at,
        started_at=job.started_at,
        finished_at=job.finished_at,
        pattern_set_id=job.meta.get("pattern_set_id"),
    )


@router.get(
    "/{job_id}",
    response_model=JobPublic,
    summary="State of a background job",
    responses={404: {"model": ErrorPublic, "description": "No such job (jobs are forgotten on restart)"}},
)
def read_job(job_id: str, jobs: JobsDep) -> JobPublic:
    """``queued`` -> ``running`` -> ``done`` | ``failed``, with progress 0..1 and, if failed, the error."""
    return job_public(jobs.get(job_id))
