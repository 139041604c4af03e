"""POST /v1/diagnose: the sim-to-real gap diagnosis (issue 4; the engine's :func:`engine.diagnosis.diagnose`)."""

from __future__ import annotations

import json
from typing import Any

from fastapi import APIRouter, Request
from starlette.concurrency import run_in_threadpool

from app.api.deps import CSV_QUERY, CSVRecordDep, body_kind, csv_record, json_body, names_another_plant, reject_query
from app.api.openapi import body_schema
from app.schemas.common import ErrorPublic
from app.schemas.diagnose import BrfdDiagnoseCreate, DiagnoseCreate, PlantDiagnoseCreate
from app.services import diagnosis, plant_diagnosis
from app.services.plant_diagnosis import PlantRecords
from engine.diagnosis.space import check_bounds
from engine.plants import get_plant
from engine.simulation import CATALOGUE

#: Request schema per plant other than the default.
PLANT_SCHEMAS: dict[str, type[PlantDiagnoseCreate] | type[BrfdDiagnoseCreate]] = {
    "emps": PlantDiagnoseCreate,
    "brfd": BrfdDiagnoseCreate,
}

router = APIRouter(prefix="/diagnose", tags=["diagnose"])


@router.post(
    "",
    summary="Diagnose the gap between a record and the model",
    openapi_extra=body_schema(DiagnoseCreate, csv=True, alternatives=tuple(PLANT_SCHEMAS.values())),
    responses={
        422: {"model": ErrorPublic, "description": "Invalid record, unknown effect, or a record the model cannot fit"},
    },
)
async def diagnose(request: Request, csv_params: CSVRecordDep) -> Any:
    """Where the record differs from the calibrated simulation, which unmodelled effect explains it and how far
    the gap shrinks with it. The body is ``{"record": ..., "effects": [...], "bounds": {...}}`` as JSON, or the
    record's CSV form
    (optionally with a ``t`` column; ``sample_interval``, ``event_index``, ``units``, ``base_torque`` and the
    known conditions as query parameters).

    ``"plant": "emps"`` diagnoses a record of the EMPS benchmark instead (``PlantDiagnoseCreate``: the record's
    signals and gains as its .mat file holds them), ``"plant": "brfd"`` one of the BRFD friction damper
    (``BrfdDiagnoseCreate``: the data set's JSON object as it is); optionally ``calibrate_on`` another record
    and ``hold_calibration``; the answer then carries ``relative_error`` before and after per channel.

    The record may be on any grid (10 us to 1 ms, any length covering the test window, the event given or
    located, any accepted units); it is fitted on its own instants, ``record`` in the answer says how it was
    read (event, window of samples used), and ``records.before`` / ``records.after`` come back on its grid and
    in its units.
    """
    bounds = None
    if body_kind(request) != "csv" and names_another_plant(await request.body()):
        reject_query(request, CSV_QUERY)
        raw = json.loads(await request.body())
        schema = PLANT_SCHEMAS.get(str(raw.get("plant")), PlantDiagnoseCreate)  # an unknown name: 422 from the schema
        other = await json_body(request, schema)
        records = PlantRecords(
            get_plant(other.plant),
            other.record.to_record(),
            other.calibrate_on.to_record() if other.calibrate_on else None,
        )
        result = await run_in_threadpool(plant_diagnosis.run, records, other.hold_calibration)
        return result.to_dict()
    if body_kind(request) == "csv":
        record, effects = await csv_record(request, csv_params), None
    else:
        reject_query(request, CSV_QUERY)
        body = await json_body(request, DiagnoseCreate)
        record, effects, bounds = body.record.to_record(), body.effects, body.bounds
    for name in effects or ():
        CATALOGUE[name]  # UnknownEffectError (422) names the known effects
    check_bounds(bounds)  # BoundsError (422) says what to fix before any work is done
    return await run_in_threadpool(diagnosis.diagnose, record, effects, bounds)
