"""Pattern sets: train one in the background, list, read and delete the stored ones."""

from __future__ import annotations

import uuid
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Query, Response, status

from app.api.deps import JobsDep, SettingsDep, StoreDep, json_model
from app.api.openapi import body_schema
from app.core.config import API_V1_STR
from app.jobs import JobManager, JobState
from app.schemas.common import ChannelName, ErrorPublic
from app.schemas.pattern_sets import PatternSetCreate, PatternSetPublic, PatternSetsPublic, TrainingAccepted
from app.services import simulation, training
from app.services.errors import NotFoundError
from app.services.identification import not_found_message
from app.services.patterns import describe, pattern_set_room
from app.services.training import TRAIN_JOB
from engine.storage import PatternSetNotFound

router = APIRouter(prefix="/pattern-sets", tags=["pattern-sets"])

#: The pattern store (SQLite) busy or unavailable (app/api/errors.py, PatternStoreError).
_STORE_BUSY: dict[int | str, dict[str, Any]] = {
    503: {"model": ErrorPublic, "description": "The pattern store is busy or unavailable; retry shortly"}
}
_NOT_FOUND: dict[int | str, dict[str, Any]] = {
    404: {"model": ErrorPublic, "description": "No pattern set with this id"},
    **_STORE_BUSY,
}


def _missing(jobs: JobManager, set_id: str) -> NotFoundError:
    """Not found; say so more helpfully when a job is (or was) training this set."""
    for job in jobs.find(pattern_set_id=set_id):
        if job.state in (JobState.queued, JobState.running):
            return NotFoundError(
                f"pattern set {set_id!r} is not stored yet: job {job.id} is training it "
                f"(state {job.state.value}, progress {job.progress:.0%}); GET {API_V1_STR}/jobs/{job.id}"
            )
        if job.state is JobState.failed:
            return NotFoundError(
                f"pattern set {set_id!r} was not stored: its training job {job.id} failed: {job.error}"
            )
    return NotFoundError(not_found_message(set_id))


@router.post(
    "",
    status_code=status.HTTP_202_ACCEPTED,
    response_model=TrainingAccepted,
    summary="Train a pattern set (background job)",
    openapi_extra=body_schema(PatternSetCreate),
    responses={
        422: {"model": ErrorPublic},
        429: {"model": ErrorPublic, "description": "Too many jobs pending"},
        507: {"model": ErrorPublic, "description": "BACKLASH_MAX_PATTERN_SETS sets are stored or being trained"},
        **_STORE_BUSY,
    },
)
def create_pattern_set(
    body: Annotated[PatternSetCreate, Depends(json_model(PatternSetCreate))],
    jobs: JobsDep,
    settings: SettingsDep,
    response: Response,
) -> Any:
    """Queue the training of one pattern set and answer at once with the job's and the set's ids.

    The job simulates the six widths x ``J1_values`` at ``c`` (with ``effects``),
    fits the identifier on ``channel`` and stores the set. Everything is validated
    before the job is queued, so a 202 means only the simulation or the fit can still
    fail (the job then ends ``failed`` with the reason, and nothing is stored). With
    ``BACKLASH_DASK_SCHEDULER`` set, the simulation and the fit run on that Dask cluster and the set is
    stored here; the job and its API are the same.

    The service keeps at most ``BACKLASH_MAX_PATTERN_SETS`` sets, counting the ones being trained: beyond,
    507 (delete unused ones first; nothing is queued).
    """
    drive = simulation.drive_of(body.drive)
    spec = training.TrainingSpec(
        channel=body.channel,
        c=body.c,
        J1_values=tuple(body.J1_values) if body.J1_values is not None else training.default_j1_values(drive),
        kind=body.kind,
        params=body.identifier_params(),
        effects=dict(body.effects),
        drive=drive,
    )
    training.check(spec)
    set_id = uuid.uuid4().hex

    job = jobs.submit(
        TRAIN_JOB,
        training.job_spec(spec, set_id),
        meta={"pattern_set_id": set_id},
        with_rows=pattern_set_room(settings.max_pattern_sets),
    )
    job_url = f"{API_V1_STR}/jobs/{job.id}"
    response.headers["Location"] = job_url
    return {
        "job_id": job.id,
        "pattern_set_id": set_id,
        "job_url": job_url,
        "pattern_set_url": f"{API_V1_STR}/pattern-sets/{set_id}",
    }


@router.get("", response_model=PatternSetsPublic, summary="List stored pattern sets", responses=_STORE_BUSY)
def list_pattern_sets(
    store: StoreDep,
    channel: Annotated[ChannelName | None, Query(description="Only sets of this channel.")] = None,
    c: Annotated[float | None, Query(allow_inf_nan=False, description="Only sets of this c [pu].")] = None,
    kind: Annotated[str | None, Query(description="Only sets of this identifier kind.")] = None,
) -> Any:
    """Stored pattern sets (metadata only), newest first."""
    sets = store.list(channel=channel, c=c, kind=kind)
    return {"data": [describe(s) for s in sets], "count": len(sets)}


@router.get("/{set_id}", response_model=PatternSetPublic, summary="Read one pattern set", responses=_NOT_FOUND)
def read_pattern_set(set_id: str, store: StoreDep, jobs: JobsDep) -> Any:
    try:
        return describe(store.get(set_id))
    except PatternSetNotFound:
        raise _missing(jobs, set_id) from None


@router.delete(
    "/{set_id}", status_code=status.HTTP_204_NO_CONTENT, summary="Delete one pattern set", responses=_NOT_FOUND
)
def delete_pattern_set(set_id: str, store: StoreDep, jobs: JobsDep) -> Response:
    try:
        store.delete(set_id)
    except PatternSetNotFound:
        raise _missing(jobs, set_id) from None
    return Response(status_code=status.HTTP_204_NO_CONTENT)
