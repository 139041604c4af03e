"""Maintenance: run the retention (deletion by age, then compaction of the database file) now."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Query, Request
from starlette.concurrency import run_in_threadpool

from app.schemas.common import ErrorPublic
from app.schemas.maintenance import RetentionPublic
from app.services.retention import RetentionScheduler

router = APIRouter(prefix="/maintenance", tags=["maintenance"])


@router.post(
    "/retention",
    response_model=RetentionPublic,
    summary="Run the retention now: delete what is older than BACKLASH_RETENTION_DAYS, then compact the file",
    responses={503: {"model": ErrorPublic, "description": "The database stayed locked; retry shortly"}},
)
async def run_retention(
    request: Request,
    compact: Annotated[bool, Query(description="Give freed pages back to the file system afterwards.")] = True,
) -> Any:
    """The run the service also makes every ``BACKLASH_RETENTION_INTERVAL_HOURS``: with
    ``BACKLASH_RETENTION_DAYS`` set, the finished jobs, diagnoses (with their figures), identifications and the
    records nothing refers to any more that were stored longer ago are deleted (never a pattern set, never a
    queued or running job's rows); without it nothing is deleted. Then the file is compacted: pages freed by
    these deletions and by every ``DELETE`` since go back to the file system. The answer says what went and the
    file's size before and after; a run under way is waited for (runs never overlap)."""
    scheduler: RetentionScheduler = request.app.state.retention
    report = await run_in_threadpool(scheduler.run_now, compact=compact)
    return report.to_dict()
