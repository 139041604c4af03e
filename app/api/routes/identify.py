"""POST /v1/identify: the backlash width of a record, from a stored pattern set."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Any

from fastapi import APIRouter, Query, Request
from starlette.concurrency import run_in_threadpool

from app.api.deps import (
    CSV_QUERY,
    CSVRecordDep,
    StoreDep,
    body_kind,
    csv_record,
    json_body,
    reject_query,
)
from app.api.openapi import body_schema
from app.schemas.common import ChannelName, ErrorPublic
from app.schemas.identify import IdentificationPublic, IdentifyCreate, PlantIdentifyCreate, PlantWidthPublic
from app.services import assets as asset_service
from app.services import identification, plant_identification, simulation
from app.services.diagnosis_requests import named_asset, named_plant
from app.services.errors import InvalidInputError

router = APIRouter(prefix="/identify", tags=["identify"])


@router.post(
    "",
    response_model=IdentificationPublic | PlantWidthPublic,
    summary="Identify the backlash width of a record",
    openapi_extra=body_schema(IdentifyCreate, csv=True, alternatives=(PlantIdentifyCreate,)),
    responses={
        400: {"model": ErrorPublic, "description": "Malformed JSON or CSV"},
        404: {"model": ErrorPublic, "description": "No (matching) pattern set stored"},
        415: {"model": ErrorPublic, "description": "Body neither JSON nor CSV"},
        422: {"model": ErrorPublic, "description": "Invalid record or request"},
    },
)
async def identify(
    request: Request,
    store: StoreDep,
    csv_params: CSVRecordDep,
    channel: Annotated[ChannelName | None, Query(description="CSV form: the channel to identify from.")] = None,
    pattern_set: Annotated[str | None, Query(description="CSV form: id of the pattern set.")] = None,
    kind: Annotated[str | None, Query(description="CSV form: only choose sets of this kind.")] = None,
    continuous: Annotated[bool, Query(description="CSV form: also the calibrated K as a continuous width.")] = False,
    any_set: Annotated[
        bool, Query(description="CSV form: also choose sets trained with effects or on another J1 grid.")
    ] = False,
) -> Any:
    """Identify with the pattern set ``pattern_set``, or else the stored set of ``channel`` whose c
    is nearest the record's ``conditions.c`` (the nominal c if the record has none); the answer
    says which set was used and why.

    A record that names its drive (``"asset"``, and ``"measured_at"`` when it was taken; CSV: query parameters)
    is stored in that drive's history (``GET /v1/assets/{asset}/history``) with its continuous width, which is
    then always computed.

    With ``continuous`` the answer also carries the calibrated K as a continuous width with
    its standard deviation (the simulator fitted to the channel; a few seconds).

    The record may be on any grid (10 us to 1 ms, any length covering the test window, the event
    given or located, any accepted units): the pattern set reads its test window resampled to
    0.1 ms, the continuous width fits it on its own instants; ``record`` in the answer says how.

    The body is ``{"record": ..., "channel": ..., "pattern_set": ..., "continuous": ...}`` as JSON,
    or the record's CSV form (``Content-Type: text/csv``, optionally with a ``t`` column) with
    ``channel``, ``pattern_set``, ``continuous``, ``sample_interval``, ``event_index``, ``units``
    (e.g. ``omega1:rpm,a1:g``), ``base_torque``, the known conditions (``c``, ``J1``, ...) and the
    ``drive`` description as JSON as query parameters.

    ``"plant": "brfd"`` identifies the width of a BRFD record instead (``PlantIdentifyCreate``: the data
    set's JSON object as it is, optionally ``joint`` records of the same device sharing one width): the
    width as a continuous parameter with its 95 % interval, or not identifiable with the reason, and the
    seed's W3/D/argmin width beside it.
    """
    # every body is parsed off the event loop (json_body, csv_record, the threads below): a large record must
    # not hold the requests that arrive meanwhile
    if csv_params.plant is not None:
        raise InvalidInputError(
            "query parameter plant: an uploaded plant's records are diagnosed (POST /v1/diagnose, POST /v1/diagnoses), "
            "not identified with pattern sets"
        )
    if body_kind(request) == "csv":
        if channel is None:
            raise InvalidInputError("with a CSV body, give the channel to identify from as query parameter ?channel=")
        csv_drive = await run_in_threadpool(simulation.drive_from_query, csv_params.drive)
        # without sample_interval or a t column, the CSV is read at the drive's protocol interval
        record = await csv_record(request, csv_params, simulation.record_interval(csv_drive))
        asset, measured_at = named_asset(csv_params.asset, csv_params.measured_at)
        args: tuple[Any, ...] = (
            record,
            channel,
            pattern_set,
            kind,
            continuous or asset is not None,
            any_set,
            csv_drive,
            None,
        )
    else:
        reject_query(request, (*CSV_QUERY, "channel", "pattern_set", "kind", "continuous", "any_set"))
        if await run_in_threadpool(named_plant, await request.body()) is not None:
            other = await json_body(request, PlantIdentifyCreate)

            def identify_plant() -> dict[str, Any]:
                records = [other.record.to_record(), *(r.to_record() for r in other.joint)]
                return plant_identification.identify_records(other.plant, records)

            answer = await run_in_threadpool(identify_plant)
            return await _keep(store, answer, other.record.asset, other.record.measured_at, None)
        body = await json_body(request, IdentifyCreate)
        asset, measured_at = body.record.asset, body.record.measured_at
        stated = None if body.record.drive is None else body.record.drive.model_dump()
        # the request's drive, else the one the record states in full (ParameterError / IncompatibleError: 422)
        drive = await run_in_threadpool(identification.drive_for_record, simulation.drive_of(body.drive), stated)
        args = (
            await run_in_threadpool(body.record.to_record, simulation.record_interval(drive)),
            body.channel,
            body.pattern_set,
            body.kind,
            body.continuous or asset is not None,
            body.any_set,
            drive,
            None if body.record.drive is None else body.record.drive.fingerprint,
        )
    answer = await run_in_threadpool(identification.identify_from_store, store, *args)
    return await _keep(store, answer, asset, measured_at, args[1])


async def _keep(
    store: Any, answer: dict[str, Any], asset: str | None, measured_at: datetime | None, channel: str | None
) -> dict[str, Any]:
    """Store the identification of a named asset (its history); the answer says where."""
    if asset is None:
        return answer
    identification_id, when = await run_in_threadpool(
        asset_service.store_identification, store, asset, measured_at, channel, answer
    )
    return {**answer, "identification_id": identification_id, "asset": asset, "measured_at": when}
