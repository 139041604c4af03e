"""The users' own plants: a description of a stored FMU, stored as a plant that diagnoses can name.

Off unless the operator turns FMU plants on (``BACKLASH_ALLOW_FMU_PLANTS``); listing and reading stay
open (they run nothing).
"""

from __future__ import annotations

import tomllib
from typing import Any

from fastapi import APIRouter, HTTPException, Request, Response, status
from pydantic import ValidationError
from starlette.concurrency import run_in_threadpool

from app.api.deps import SettingsDep, StoreDep, body_errors
from app.api.openapi import body_schema
from app.db.plants import PlantRepository, StoredPlant
from app.schemas.common import ErrorPublic
from app.schemas.plants import EffectPublic, PlantCreate, PlantPublic, PlantsPublic
from app.services import plants
from app.services.errors import InvalidInputError

router = APIRouter(prefix="/plants", tags=["plants"])

_NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": ErrorPublic, "description": "No such plant"}}
#: Content types of a description sent as its TOML file.
TOML_MEDIA_TYPES = ("application/toml", "text/toml", "text/x-toml")


def plant_public(stored: StoredPlant, plant: Any) -> PlantPublic:
    d = plant.description
    return PlantPublic(
        id=stored.id,
        name=stored.name,
        fmu_sha256=stored.fmu_sha256,
        created_at=stored.created_at,
        loci=list(plant.loci),
        channels=[c.name for c in plant.channels],
        columns=[d.time, *(str(i.column) for i in d.driven), *(c.name for c in d.channels)],
        calibrated=[c.name for c in plant.calibrated],
        effects=[
            EffectPublic(name=e.name, locus=e.locus, unit=e.unit, bounds=tuple(e.bounds), description=e.description)
            for e in plant.catalogue.values()
        ],
        description=stored.description,
    )


def _read_description(raw: bytes, media: str) -> dict[str, Any]:
    if media in TOML_MEDIA_TYPES:
        try:
            return tomllib.loads(raw.decode("utf-8-sig"))
        except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
            raise InvalidInputError(f"the body is not a TOML plant description: {exc}") from None
    try:
        return PlantCreate.model_validate_json(raw).description
    except ValidationError as exc:
        raise body_errors(exc) from None


@router.post(
    "",
    response_model=PlantPublic,
    status_code=status.HTTP_201_CREATED,
    summary="Store a plant: a description of an uploaded FMU",
    openapi_extra=body_schema(PlantCreate),
    responses={
        200: {"model": PlantPublic, "description": "This description of this FMU was stored already"},
        403: {"model": ErrorPublic, "description": "FMU plants are turned off on this service"},
        422: {"model": ErrorPublic, "description": "A description the plant cannot use; the message names the key"},
        507: {"model": ErrorPublic, "description": "BACKLASH_MAX_PLANTS plants are stored"},
    },
)
async def create_plant(request: Request, response: Response, store: StoreDep, settings: SettingsDep) -> Any:
    """The body is ``{"description": {...}}`` (JSON), or the description's TOML file as it is
    (``Content-Type: application/toml``); either way its ``fmu`` is ``"sha256:<hex>"`` of an archive
    ``POST /v1/fmus`` stored. The description is checked against the FMU's variables as ``--plant plant.toml``
    is (nothing of the FMU runs); the answer's ``id`` names the plant in diagnoses. The same description of the
    same FMU is the same plant: sending it again stores nothing and answers 200."""
    plants.require_enabled(settings)
    media = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if media not in ("", "application/json", *TOML_MEDIA_TYPES):
        raise HTTPException(
            415,
            f'unsupported Content-Type {media!r}: send {{"description": ...}} as application/json, or the '
            "description's TOML file as application/toml",
        )
    raw = await request.body()
    description = await run_in_threadpool(_read_description, raw, media)
    stored, created = await run_in_threadpool(plants.add_plant, store, settings, description)
    plant = await run_in_threadpool(plants.load, store.path, stored.id)
    response.status_code = status.HTTP_201_CREATED if created else status.HTTP_200_OK
    response.headers["Location"] = f"/v1/plants/{stored.id}"
    return plant_public(stored, plant)


@router.get("", response_model=PlantsPublic, summary="List stored plants")
def list_plants(store: StoreDep) -> Any:
    stored = PlantRepository(store).list_plants()
    return PlantsPublic(items=[plant_public(p, plants.load(store.path, p.id)) for p in stored])


@router.get("/{plant_id}", response_model=PlantPublic, summary="A stored plant", responses=_NOT_FOUND)
def read_plant(plant_id: str, store: StoreDep) -> Any:
    stored = plants.get_plant(store, plant_id)
    return plant_public(stored, plants.load(store.path, stored.id))


@router.delete(
    "/{plant_id}",
    status_code=status.HTTP_204_NO_CONTENT,
    response_class=Response,
    summary="Delete a stored plant (and its FMU, when no other plant uses it)",
    responses={**_NOT_FOUND, 409: {"model": ErrorPublic, "description": "Stored records name the plant"}},
)
def delete_plant(plant_id: str, store: StoreDep) -> Response:
    """Refused (409) while stored records name the plant: they could not be read again without it."""
    plants.delete_plant(store, plant_id)
    return Response(status_code=status.HTTP_204_NO_CONTENT)
