"""POST /v1/simulate and /v1/simulate/batch: the backlash test of one or several cases, rendered as a bench gives it."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Depends, Request, Response

from app.api.deps import SettingsDep, json_model
from app.api.openapi import body_schema
from app.records_io import format_units, record_to_csv
from app.schemas.common import ErrorPublic
from app.schemas.simulate import SimulateBatchCreate, SimulateCase, SimulateCreate, SimulationPublic, SimulationsPublic
from app.services import simulation
from app.services.errors import InvalidInputError
from engine.records import Record
from engine.simulation.drive import DriveDescription

router = APIRouter(prefix="/simulate", tags=["simulate"])

_ERRORS: dict[int | str, dict[str, Any]] = {
    422: {
        "model": ErrorPublic,
        "description": "Out-of-range parameter, unknown effect or unit, an impossible drive description, a grid "
        "that cannot hold the test, or no backlash event",
    }
}


def _simulate(
    cases: list[SimulateCase], rendering: simulation.Rendering, drive: DriveDescription | None
) -> list[Record]:
    prepared = simulation.prepare(
        [simulation.make_case(c.K, c.J1, c.c, c.c1, drive) for c in cases], [c.effects for c in cases]
    )
    return simulation.render(prepared, rendering, drive)


def _wants_csv(request: Request) -> bool:
    accept = request.headers.get("accept", "").lower()
    return "text/csv" in accept and "application/json" not in accept


@router.post(
    "",
    response_model=SimulationPublic,
    response_model_exclude_none=True,
    summary="Simulate one case",
    openapi_extra=body_schema(SimulateCreate),
    responses={
        **_ERRORS,
        200: {
            "content": {"text/csv": {"schema": {"type": "string"}}},
            "description": "The record (CSV form with Accept: text/csv; headers X-Sample-Interval, "
            "X-Event-Index (unless include_event_index is false), X-Event-Time, when some channel is not "
            "in its model unit, X-Units as CHANNEL:UNIT pairs separated by commas, and with a drive description "
            "X-Drive-Fingerprint)",
        },
    },
)
def simulate(body: Annotated[SimulateCreate, Depends(json_model(SimulateCreate))], request: Request) -> Any:
    """Run the backlash test of MODEL.md for one case and return its record plus ``event_time``.

    The record is rendered on the grid ``sample_interval`` [s], from ``before`` [s] before the
    event to ``after`` [s] after it, with the ``channels`` asked for in the ``units`` asked for;
    ``include_event_index: false`` leaves the event index out, so that a reader has to locate it.

    With ``Accept: text/csv`` the record comes in CSV form (a header row of channel names,
    optionally ``t`` first with ``time_column``; one row per sample) and Ts, the event index,
    t_e and the units in response headers.

    With ``drive`` (a drive description, docs/drive-description.md) the case is that drive's nominal
    plant (the K, J1, c and c1 given override it), simulated within its ``t_event_max`` and rendered on
    its protocol's grid unless ``sample_interval``, ``before`` or ``after`` are given; the record carries
    ``drive`` (the description's fingerprint and content) and states the drive's base torque. A
    description the engine refuses is a 422 that names the key and what to fix.
    """
    drive = simulation.drive_of(body.drive)
    rendering = body.rendering(simulation.protocol_span(drive))
    record = _simulate([body], rendering, drive)[0]
    if _wants_csv(request):
        headers = {"X-Sample-Interval": repr(record.sample_interval), "X-Event-Time": repr(record.event_time)}
        if rendering.include_event_index:
            headers["X-Event-Index"] = str(record.event_index)
        if record.units:
            headers["X-Units"] = format_units(record.units)
        if drive is not None:
            headers["X-Drive-Fingerprint"] = drive.fingerprint
        return Response(record_to_csv(record, with_time=body.time_column), media_type="text/csv", headers=headers)
    return simulation.to_public(record, rendering, drive)


@router.post(
    "/batch",
    response_model=SimulationsPublic,
    response_model_exclude_none=True,
    summary="Simulate several cases",
    openapi_extra=body_schema(SimulateBatchCreate),
    responses=_ERRORS,
)
def simulate_batch(
    body: Annotated[SimulateBatchCreate, Depends(json_model(SimulateBatchCreate))], settings: SettingsDep
) -> Any:
    """Run the backlash test for every case, in order, all rendered the same way (the same options as
    ``POST /v1/simulate``, given once beside ``cases``); at most BACKLASH_MAX_BATCH_CASES cases.
    """
    if len(body.cases) > settings.max_batch_cases:
        raise InvalidInputError(
            f"the batch has {len(body.cases)} cases; at most {settings.max_batch_cases} are allowed per request "
            "(BACKLASH_MAX_BATCH_CASES): split it into several requests"
        )
    drive = simulation.drive_of(body.drive)
    rendering = body.rendering(simulation.protocol_span(drive))
    records = _simulate(body.cases, rendering, drive)
    return {"data": [simulation.to_public(r, rendering, drive) for r in records], "count": len(records)}
