"""Diagnoses as stored jobs: submit (202), read, list by asset, delete, and their figures."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Request, Response, status
from pydantic import ValidationError
from starlette.concurrency import run_in_threadpool

from app.api.deps import CSVRecordDep, JobsDep, StoreDep, body_errors, diagnosis_request
from app.api.openapi import body_schema
from app.core.config import API_V1_STR
from app.db.diagnoses import DiagnosisRepository, StoredDiagnosis
from app.jobs import Job, JobManager
from app.schemas.assets import AssetName
from app.schemas.common import ErrorPublic
from app.schemas.diagnose import DiagnoseCreate, DiagnosesPublic, DiagnosisAccepted, DiagnosisPublic
from app.services import diagnoses
from app.services.diagnosis_requests import PLANT_SCHEMAS
from app.services.errors import NotFoundError

router = APIRouter(prefix="/diagnoses", tags=["diagnoses"])

_NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": ErrorPublic, "description": "No such diagnosis"}}


def diagnosis_public(d: StoredDiagnosis, jobs: JobManager) -> DiagnosisPublic:
    return DiagnosisPublic(
        id=d.id,
        job_id=d.job_id,
        record_id=d.record_id,
        plant=d.plant,
        asset=d.asset,
        measured_at=d.measured_at,
        created_at=d.created_at,
        state=diagnoses.job_state(jobs, d),
        status=d.status,
        effect=d.effect,
        K=d.width,
        K_sigma=d.width_sigma,
        figures=list(d.figures),
        result=d.result,
    )


def accepted(job: Job, diagnosis_id: str, record_id: str, response: Response) -> DiagnosisAccepted:
    """The 202 answer of a queued diagnosis, with its ``Location``."""
    url = f"{API_V1_STR}/diagnoses/{diagnosis_id}"
    response.headers["Location"] = url
    return DiagnosisAccepted(
        job_id=job.id,
        diagnosis_id=diagnosis_id,
        record_id=record_id,
        job_url=f"{API_V1_STR}/jobs/{job.id}",
        diagnosis_url=url,
    )


@router.post(
    "",
    status_code=status.HTTP_202_ACCEPTED,
    response_model=DiagnosisAccepted,
    summary="Diagnose a record as a background job (stored)",
    openapi_extra=body_schema(DiagnoseCreate, csv=True, alternatives=tuple(PLANT_SCHEMAS.values())),
    responses={
        400: {"model": ErrorPublic, "description": "Unreadable record"},
        422: {"model": ErrorPublic, "description": "Invalid record or request"},
        429: {"model": ErrorPublic, "description": "Too many jobs pending"},
    },
)
async def create_diagnosis(
    request: Request, csv_params: CSVRecordDep, store: StoreDep, jobs: JobsDep, response: Response
) -> Any:
    """The body of ``POST /v1/diagnose`` (JSON, or a record's CSV form). The record may name its drive
    (``"asset"``) and when it was taken (``"measured_at"``, ISO 8601 with a UTC offset; CSV: query parameters);
    without ``measured_at`` the time of receipt is stored.

    Everything is checked before the answer: a 202 means the record is stored (``GET /v1/records/{record_id}``)
    and the job queued (``GET /v1/jobs/{job_id}`` for its progress, ``DELETE`` to cancel it); the result is
    read at ``GET /v1/diagnoses/{diagnosis_id}`` once the job is done.
    """
    sent = await diagnosis_request(request, csv_params)
    try:
        job, diagnosis_id, record = await run_in_threadpool(diagnoses.submit, store, jobs, sent)
    except ValidationError as exc:
        raise body_errors(exc) from None
    return accepted(job, diagnosis_id, record.id, response)


@router.get("", response_model=DiagnosesPublic, summary="List stored diagnoses")
def list_diagnoses(
    store: StoreDep,
    jobs: JobsDep,
    asset: Annotated[AssetName | None, Query(description="Only diagnoses of this asset.")] = None,
    limit: Annotated[int, Query(ge=1, le=1000, description="At most this many, newest first.")] = 100,
) -> Any:
    found = DiagnosisRepository(store).list(asset=asset, limit=limit)
    return DiagnosesPublic(items=[diagnosis_public(d, jobs) for d in found])


@router.get("/{diagnosis_id}", response_model=DiagnosisPublic, summary="A stored diagnosis", responses=_NOT_FOUND)
def read_diagnosis(diagnosis_id: str, store: StoreDep, jobs: JobsDep) -> Any:
    """The job's state and, once it is done, the result (the answer of ``POST /v1/diagnose``) and figure names."""
    return diagnosis_public(diagnoses.get(store, diagnosis_id), jobs)


@router.delete(
    "/{diagnosis_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    response_class=Response,
    summary="Delete a diagnosis (cancelling its job if it still runs)",
    responses=_NOT_FOUND,
)
def delete_diagnosis(diagnosis_id: str, store: StoreDep, jobs: JobsDep) -> Response:
    """The stored record stays (``DELETE /v1/records/{id}`` removes it)."""
    diagnoses.delete(store, jobs, diagnosis_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.get(
    "/{diagnosis_id}/figures/{name}",
    response_class=Response,
    summary="A figure of a diagnosis (PNG)",
    responses={
        200: {
            "content": {"image/png": {"schema": {"type": "string", "format": "binary"}}},
            "description": "The figure",
        },
        **_NOT_FOUND,
    },
)
def read_figure(diagnosis_id: str, name: str, store: StoreDep) -> Response:
    """Names are listed in the diagnosis's ``figures``: residual maps, record-vs-simulation overlays, the
    missing term of a gap outside the catalogue, the plants' own figures."""
    found = diagnoses.get(store, diagnosis_id, with_result=False)
    png = DiagnosisRepository(store).figure(diagnosis_id, name)
    if png is None:
        listed = ", ".join(found.figures) or "none yet"
        raise NotFoundError(f"diagnosis {diagnosis_id} has no figure {name!r} (it has: {listed})")
    return Response(png, media_type="image/png", headers={"Cache-Control": "private, max-age=3600"})
