"""FMU archives of the users' own simulators: upload one (stored once, by its SHA-256), read what it is.

Off unless the operator turns FMU plants on (``BACKLASH_ALLOW_FMU_PLANTS``): an FMU is native code
the diagnosis workers run (docs/fmu-plant.md, section "On the service").
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, HTTPException, Request, Response, status
from starlette.concurrency import run_in_threadpool

from app.api.deps import SettingsDep, StoreDep
from app.db.plants import PlantRepository, StoredFmu
from app.schemas.common import ErrorPublic
from app.schemas.plants import FmuPublic
from app.services import plants
from app.services.errors import InvalidInputError, NotFoundError

router = APIRouter(prefix="/fmus", tags=["plants"])

#: Content types an FMU archive may be sent with.
FMU_MEDIA_TYPES = ("application/octet-stream", "application/zip", "application/x-fmu")


def fmu_public(stored: StoredFmu) -> FmuPublic:
    s = stored.summary
    return FmuPublic(
        sha256=stored.sha256,
        size=stored.size,
        model_name=s["model_name"],
        fmi_version=s["fmi_version"],
        platforms=list(s["platforms"]),
        interfaces=list(s.get("interfaces", ["co-simulation"])),  # stored before model exchange: co-simulation only
        inputs=list(s["inputs"]),
        outputs=list(s["outputs"]),
        parameters=list(s["parameters"]),
        created_at=stored.created_at,
    )


@router.post(
    "",
    response_model=FmuPublic,
    status_code=status.HTTP_201_CREATED,
    summary="Upload an FMU (stored once, by its SHA-256)",
    openapi_extra={
        "requestBody": {
            "required": True,
            # application/zip and application/x-fmu are accepted too; one media type is documented
            "content": {"application/octet-stream": {"schema": {"type": "string", "format": "binary"}}},
        }
    },
    responses={
        200: {"model": FmuPublic, "description": "This archive was stored already"},
        403: {"model": ErrorPublic, "description": "FMU plants are turned off on this service"},
        413: {"model": ErrorPublic, "description": "Larger than BACKLASH_MAX_FMU_BYTES"},
        422: {
            "model": ErrorPublic,
            "description": "Not an FMI 2.0 FMU (co-simulation or model exchange) with a binary for this machine",
        },
    },
)
async def upload_fmu(request: Request, response: Response, store: StoreDep, settings: SettingsDep) -> Any:
    """The body is the ``.fmu`` file as it was exported (``Content-Type: application/octet-stream``). It is checked
    as a file (its size, what it unpacks to, that it is FMI 2.0, co-simulation or model exchange, with a binary for this machine) and
    stored; nothing of it runs. The answer's ``sha256`` names it in a plant description (``POST /v1/plants``).
    Sending the same archive again stores nothing and answers 200."""
    plants.require_enabled(settings)
    media = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if media not in FMU_MEDIA_TYPES:
        raise HTTPException(
            415,
            f"unsupported Content-Type {media!r}: send the .fmu file as the body with Content-Type: "
            "application/octet-stream",
        )
    content = await request.body()
    if not content:
        raise InvalidInputError("the body is empty: send the .fmu file's bytes")
    stored, created = await run_in_threadpool(plants.add_fmu, store, settings, content)
    response.status_code = status.HTTP_201_CREATED if created else status.HTTP_200_OK
    response.headers["Location"] = f"/v1/fmus/{stored.sha256}"
    return fmu_public(stored)


@router.get(
    "/{sha256}",
    response_model=FmuPublic,
    summary="A stored FMU's metadata",
    responses={404: {"model": ErrorPublic, "description": "No such FMU"}},
)
def read_fmu(sha256: str, store: StoreDep) -> Any:
    found = PlantRepository(store).get_fmu(sha256.lower()) if len(sha256) == 64 else None
    if found is None:
        raise NotFoundError(f"no FMU with SHA-256 {sha256[:100]!r} is stored; upload it with POST /v1/fmus")
    return fmu_public(found)
