"""POST /v1/simulate and /v1/simulate/batch: the backlash test of one or several cases."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request, Response

from app.api.deps import SettingsDep
from app.records_io import record_to_csv
from app.schemas.common import ErrorPublic
from app.schemas.simulate import SimulateBatchCreate, SimulateCreate, SimulationPublic, SimulationsPublic
from app.services import simulation
from app.services.errors import InvalidInputError
from engine.records import Record

router = APIRouter(prefix="/simulate", tags=["simulate"])

_ERRORS: dict[int | str, dict[str, Any]] = {
    422: {"model": ErrorPublic, "description": "Out-of-range parameter, unknown effect, or no backlash event"}
}


def _simulate(cases: list[SimulateCreate]) -> list[Record]:
    prepared = simulation.prepare(
        [simulation.make_case(c.K, c.J1, c.c, c.c1) for c in cases], [c.effects for c in cases]
    )
    return simulation.run(prepared).records


def _wants_csv(request: Request) -> bool:
    accept = request.headers.get("accept", "").lower()
    return "text/csv" in accept and "application/json" not in accept


@router.post(
    "",
    response_model=SimulationPublic,
    summary="Simulate one case",
    responses={
        **_ERRORS,
        200: {
            "content": {"text/csv": {}},
            "description": "The record (CSV form with Accept: text/csv; "
            "headers X-Sample-Interval, X-Event-Index, X-Event-Time)",
        },
    },
)
def simulate(body: SimulateCreate, request: Request) -> Any:
    """Run the backlash test of MODEL.md for one case and return its record plus ``event_time``.

    With ``Accept: text/csv`` the record comes in CSV form (a header row of channel
    names, one row per sample) and Ts, the event index and t_e in response headers.
    """
    record = _simulate([body])[0]
    if _wants_csv(request):
        return Response(
            record_to_csv(record),
            media_type="text/csv",
            headers={
                "X-Sample-Interval": repr(record.sample_interval),
                "X-Event-Index": str(record.event_index),
                "X-Event-Time": repr(record.event_time),
            },
        )
    return record.to_dict()


@router.post("/batch", response_model=SimulationsPublic, summary="Simulate several cases", responses=_ERRORS)
def simulate_batch(body: SimulateBatchCreate, settings: SettingsDep) -> Any:
    """Run the backlash test for every case, in order; at most BACKLASH_MAX_BATCH_CASES cases."""
    if len(body.cases) > settings.max_batch_cases:
        raise InvalidInputError(
            f"the batch has {len(body.cases)} cases; at most {settings.max_batch_cases} are allowed per request "
            "(BACKLASH_MAX_BATCH_CASES): split it into several requests"
        )
    records = _simulate(body.cases)
    return {"data": [r.to_dict() for r in records], "count": len(records)}
