"""POST /v1/diagnose: the sim-to-real gap diagnosis, synchronously (the engine's :func:`engine.diagnosis.diagnose`).

For long records or many at once, ``POST /v1/diagnoses`` runs the same diagnosis as a stored job.
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any

from fastapi import APIRouter, Request, Response
from pydantic import ValidationError
from starlette.concurrency import run_in_threadpool

from app.api.deps import CSVRecordDep, SyncDiagnosesDep, body_errors, diagnosis_request
from app.api.openapi import body_schema
from app.schemas.common import ErrorPublic
from app.schemas.diagnose import DiagnoseCreate, DiagnosisAnswer
from app.services.diagnosis_requests import PLANT_SCHEMAS, DiagnosisRequest, parse

logger = logging.getLogger(__name__)

router = APIRouter(prefix="/diagnose", tags=["diagnose"])

#: How often [s] a running synchronous diagnosis checks whether its client is still there.
DISCONNECT_POLL = 0.25
#: Status logged for a request whose client disconnected before the answer (nginx's "client closed request").
CLIENT_CLOSED_REQUEST = 499


@router.post(
    "",
    summary="Diagnose the gap between a record and the model (synchronous)",
    response_model=DiagnosisAnswer,
    openapi_extra=body_schema(DiagnoseCreate, csv=True, alternatives=tuple(PLANT_SCHEMAS.values())),
    responses={
        422: {"model": ErrorPublic, "description": "Invalid record, unknown effect, or a record the model cannot fit"},
        429: {"model": ErrorPublic, "description": "Too many synchronous diagnoses at once (see Retry-After)"},
        504: {"model": ErrorPublic, "description": "The diagnosis ran past the time limit and was stopped"},
    },
)
async def diagnose(request: Request, csv_params: CSVRecordDep, sync: SyncDiagnosesDep) -> Any:
    """Where the record differs from the calibrated simulation, which unmodelled effect explains it and how far
    the gap shrinks with it. The body is ``{"record": ..., "effects": [...], "bounds": {...}}`` as JSON, or the
    record's CSV form
    (optionally with a ``t`` column; ``sample_interval``, ``event_index``, ``units``, ``base_torque``, the
    known conditions and the ``drive`` description as JSON as query parameters).

    ``"plant": "emps"`` diagnoses a record of the EMPS benchmark instead (``PlantDiagnoseCreate``: the record's
    signals and gains as its .mat file holds them), ``"plant": "brfd"`` one of the BRFD friction damper
    (``BrfdDiagnoseCreate``: the data set's JSON object as it is); optionally ``calibrate_on`` another record
    and ``hold_calibration``; the answer then carries ``relative_error`` before and after per channel.

    The record may be on any grid (10 us to 1 ms, any length covering the test window, the event given or
    located, any accepted units); it is fitted on its own instants, ``record`` in the answer says how it was
    read (event, window of samples used), and ``records.before`` / ``records.after`` come back on its grid and
    in its units.

    At most ``BACKLASH_MAX_SYNC_DIAGNOSES`` run at once (429 with ``Retry-After`` beyond), each within
    ``BACKLASH_SYNC_DIAGNOSE_TIMEOUT`` seconds (504 beyond, the work stopped); a client that disconnects
    stops its diagnosis and frees its place at once. Nothing is stored: submit to
    ``POST /v1/diagnoses`` to keep the result, follow its progress, or cancel it.
    """
    sent = await diagnosis_request(request, csv_params)
    await run_in_threadpool(check, sent)  # every input error answered here (422/400), before a worker is used
    future = sync.start(sent)  # QueueFullError (429) when every slot is taken
    waiting = asyncio.wrap_future(future)
    while not (await asyncio.wait({waiting}, timeout=DISCONNECT_POLL))[0]:
        if await request.is_disconnected():  # the client gave up: its slot and its worker's core are freed now
            future.cancel()
            logger.info("POST %s: the client disconnected; its synchronous diagnosis was stopped", request.url.path)
            return Response(status_code=CLIENT_CLOSED_REQUEST)
    if not waiting.cancelled():
        waiting.exception()  # marks it retrieved: sync.result raises it as the service's error
    return sync.result(future)


def check(sent: DiagnosisRequest) -> None:
    """Read the request as the worker will (in a thread: a large body must not hold the event loop)."""
    try:
        parse(sent)
    except ValidationError as exc:
        raise body_errors(exc) from None
