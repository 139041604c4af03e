"""GET /healthz: liveness and readiness (the store answers). Never needs the API key, but says more with it."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

import anyio.to_thread
from fastapi import APIRouter, Request

from app.api.deps import SettingsDep, StoreDep
from app.api.middleware import API_KEY_HEADER, key_matches
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
    response_model_exclude_none=True,
    summary="Health check",
    responses={503: {"model": ErrorPublic, "description": "The pattern store does not answer"}},
    openapi_extra={"security": []},  # never needs the API key
)
async def healthz(request: Request, store: StoreDep, settings: SettingsDep) -> HealthPublic:
    """``ok`` when the service runs and its pattern store answers (503 otherwise). Never needs the API key; without
    it (when the service has one) the answer is ``{"status": "ok"}`` alone, with it also the versions and the
    number of stored pattern sets."""
    # its own threads (app.main's lifespan): never queued behind the requests that compute
    count = await anyio.to_thread.run_sync(len, store, limiter=request.app.state.health_threads)
    key = settings.api_key
    if key is not None and not key_matches(request.headers.get(API_KEY_HEADER), key.get_secret_value()):
        return HealthPublic(status="ok")
    return HealthPublic(status="ok", version=package_version(), model_version=MODEL_VERSION, pattern_sets=count)
