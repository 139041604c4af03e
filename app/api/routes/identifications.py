"""Stored identifications of named assets: delete one (it leaves the asset's history and trend)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Response, status

from app.api.deps import StoreDep
from app.schemas.common import ErrorPublic
from app.services import retention

router = APIRouter(prefix="/identifications", tags=["identify"])

_NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": ErrorPublic, "description": "No such identification"}}


@router.delete(
    "/{identification_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    response_class=Response,
    summary="Delete a stored identification",
    responses=_NOT_FOUND,
)
def delete_identification(identification_id: str, store: StoreDep) -> Response:
    """The identification (``identification_id`` of a ``POST /v1/identify`` answer, ``id`` of a history point)
    leaves its asset's history and trend. Nothing else refers to an identification."""
    retention.delete_identification(store, identification_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
