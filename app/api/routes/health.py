"""GET /healthz: liveness and readiness (the store answers). Never needs the API key."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

from fastapi import APIRouter
from starlette.concurrency import run_in_threadpool

from app.api.deps import StoreDep
from app.schemas.common import ErrorPublic
from app.schemas.health import HealthPublic
from engine.constants import MODEL_VERSION

router = APIRouter(tags=["health"])


def package_version() -> str:
    try:
        return version("backlash")
    except PackageNotFoundError:  # running from a source tree that is not installed
        return "unknown"


@router.get(
    "/healthz",
    response_model=HealthPublic,
    summary="Health check",
    responses={503: {"model": ErrorPublic, "description": "The pattern store does not answer"}},
)
async def healthz(store: StoreDep) -> HealthPublic:
    """``ok`` when the service runs and its pattern store answers (503 otherwise)."""
    count = await run_in_threadpool(len, store)
    return HealthPublic(status="ok", version=package_version(), model_version=MODEL_VERSION, pattern_sets=count)
