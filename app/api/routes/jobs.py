"""Background jobs: state and progress, list, cancel, retry (persisted: they survive a restart)."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Response, status

from app.api.deps import JobsDep, StoreDep
from app.core.config import API_V1_STR
from app.jobs import Job, JobState
from app.schemas.common import ErrorPublic
from app.schemas.jobs import JobPublic, JobsPublic, JobStateName
from app.services import jobs as job_service
from app.services import retention

router = APIRouter(prefix="/jobs", tags=["jobs"])

_NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": ErrorPublic, "description": "No such job"}}


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
        diagnosis_id=job.meta.get("diagnosis_id"),
        retry_of=job.retry_of,
    )


@router.get("", response_model=JobsPublic, summary="List jobs")
def list_jobs(
    jobs: JobsDep,
    state: Annotated[JobStateName | None, Query(description="Only jobs in this state.")] = None,
    kind: Annotated[str | None, Query(max_length=100, description="Only jobs of this kind.")] = None,
    limit: Annotated[int, Query(ge=1, le=1000, description="At most this many, newest first.")] = 100,
) -> Any:
    found = jobs.list(kind=kind, state=JobState(state) if state else None, limit=limit)
    return JobsPublic(items=[job_public(j) for j in found])


@router.get("/{job_id}", response_model=JobPublic, summary="State of a background job", responses=_NOT_FOUND)
def read_job(job_id: str, jobs: JobsDep) -> JobPublic:
    """``queued`` -> ``running`` -> ``done`` | ``failed`` | ``cancelled`` (or ``interrupted`` by a restart), with
    progress 0..1 and the error when it did not finish well."""
    return job_public(jobs.get(job_id))


@router.post(
    "/{job_id}/cancel",
    response_model=JobPublic,
    summary="Cancel a queued or running job",
    responses={**_NOT_FOUND, 409: {"model": ErrorPublic, "description": "The job has already finished"}},
)
def cancel_job(job_id: str, jobs: JobsDep) -> JobPublic:
    """A queued job never starts; a running diagnosis's worker process is stopped at once (its core is free); a
    running training stops at its next progress report. The job's record stays, in state ``cancelled``
    (``DELETE /v1/jobs/{id}`` then removes it)."""
    return job_public(jobs.cancel(job_id))


@router.post(
    "/{job_id}/retry",
    status_code=status.HTTP_202_ACCEPTED,
    response_model=JobPublic,
    summary="Run a failed, interrupted or cancelled job again (idempotent)",
    responses={
        **_NOT_FOUND,
        200: {
            "model": JobPublic,
            "description": "A retry of this job (or of its retries) is already queued, running or done: that job, "
            "nothing new is run",
        },
        202: {
            "model": JobPublic,
            "description": "A new job (queued; or done at once when the result was already stored)",
        },
        409: {"model": ErrorPublic, "description": "The job itself is queued, running or done: nothing to retry"},
        429: {"model": ErrorPublic, "description": "Too many jobs pending"},
    },
)
def retry_job(job_id: str, jobs: JobsDep, store: StoreDep, response: Response) -> JobPublic:
    """A new job with the same request (``retry_of`` names the job it re-runs); a diagnosis keeps its id and now
    follows the new job; a training stores its set under the id announced the first time.

    Idempotent: a job has at most one retry queued or running. Asking again while a retry of it (or of its
    retries) is queued, running or done answers **200** with that job and runs nothing; after that retry ends
    failed, interrupted or cancelled, asking again retries *it* (the newest of the chain). A job whose result is
    already stored (a pattern set, a diagnosis's result) is not run again: its retry is ``done`` at once (202, stage
    says so). A job that is itself queued, running or done cannot be retried (**409**)."""
    retried = job_service.retry(store, jobs, job_id)
    response.headers["Location"] = f"{API_V1_STR}/jobs/{retried.job.id}"
    if not retried.created:
        response.status_code = status.HTTP_200_OK
    return job_public(retried.job)


@router.delete(
    "/{job_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    response_class=Response,
    summary="Delete a finished job",
    responses={
        **_NOT_FOUND,
        409: {
            "model": ErrorPublic,
            "description": "The job is queued or running (cancel it first: POST /v1/jobs/{id}/cancel), or another "
            "row needs it (a diagnosis without a result follows it, or a later job re-runs it); the message says "
            "which",
        },
    },
)
def delete_job(job_id: str, store: StoreDep) -> Response:
    """Remove a done, failed, interrupted or cancelled job. A diagnosis with a result keeps it (its state reads
    ``done``); one without a result needs its job (delete the diagnosis first, or retry the job); a job that a
    retry names (``retry_of``) goes after the retry."""
    retention.delete_job(store, job_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
