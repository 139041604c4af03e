"""Stored records: list, read (metadata, the body as sent), diagnose again, delete."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Response, status
from starlette.concurrency import run_in_threadpool

from app.api.deps import JobsDep, StoreDep
from app.api.routes.diagnoses import accepted
from app.db.records import RecordRepository, StoredRecord
from app.schemas.assets import AssetName
from app.schemas.common import ErrorPublic
from app.schemas.diagnose import DiagnosisAccepted
from app.schemas.records import RecordPublic, RecordsPublic
from app.services import diagnoses
from app.services.errors import NotFoundError

router = APIRouter(prefix="/records", tags=["records"])

_NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": ErrorPublic, "description": "No such record"}}


def record_public(r: StoredRecord) -> RecordPublic:
    return RecordPublic(
        id=r.id,
        plant=r.plant,
        name=r.name,
        asset=r.asset,
        measured_at=r.measured_at,
        n_samples=r.n_samples,
        created_at=r.created_at,
        media=r.media,
        params=r.params,
    )


def _get(store: Any, record_id: str) -> StoredRecord:
    found = RecordRepository(store).get(record_id)
    if found is None:
        raise NotFoundError(f"no record with id {record_id!r}; GET /v1/records lists the stored ones")
    return found


@router.get("", response_model=RecordsPublic, summary="List stored records")
def list_records(
    store: StoreDep,
    asset: Annotated[AssetName | None, Query(description="Only records of this asset.")] = None,
    limit: Annotated[int, Query(ge=1, le=1000, description="At most this many, newest first.")] = 100,
) -> Any:
    return RecordsPublic(items=[record_public(r) for r in RecordRepository(store).list(asset=asset, limit=limit)])


@router.get("/{record_id}", response_model=RecordPublic, summary="A stored record's metadata", responses=_NOT_FOUND)
def read_record(record_id: str, store: StoreDep) -> Any:
    return record_public(_get(store, record_id))


@router.get(
    "/{record_id}/body",
    response_class=Response,
    summary="A stored record's body, as it was sent",
    responses={
        200: {
            "content": {"application/json": {"schema": {"type": "object"}}, "text/csv": {"schema": {"type": "string"}}},
            "description": "The body as sent",
        },
        **_NOT_FOUND,
    },
)
def read_record_body(record_id: str, store: StoreDep) -> Response:
    """JSON as sent, or the CSV text (whose query parameters are the record's ``params``)."""
    found = _get(store, record_id)
    media = "application/json" if found.media == "json" else "text/csv; charset=utf-8"
    return Response(found.body or b"", media_type=media)


@router.post(
    "/{record_id}/diagnoses",
    status_code=status.HTTP_202_ACCEPTED,
    response_model=DiagnosisAccepted,
    summary="Diagnose a stored record again (background job)",
    responses={**_NOT_FOUND, 429: {"model": ErrorPublic, "description": "Too many jobs pending"}},
)
async def diagnose_record(record_id: str, store: StoreDep, jobs: JobsDep, response: Response) -> Any:
    found = _get(store, record_id)
    job, diagnosis_id = await run_in_threadpool(diagnoses.submit_stored, store, jobs, found)
    return accepted(job, diagnosis_id, found.id, response)


@router.delete(
    "/{record_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    response_class=Response,
    summary="Delete a stored record",
    responses=_NOT_FOUND,
)
def delete_record(record_id: str, store: StoreDep) -> Response:
    """Its diagnoses keep their results; one not yet run fails, saying the record was deleted."""
    _get(store, record_id)
    RecordRepository(store).delete(record_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
