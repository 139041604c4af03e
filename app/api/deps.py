"""Dependencies of the routes: settings, the pattern store, the job manager, record bodies."""

from __future__ import annotations

from collections.abc import Callable, Coroutine
from typing import Annotated, Any, Literal, TypeVar

from fastapi import Depends, HTTPException, Query, Request
from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, ValidationError
from starlette.concurrency import run_in_threadpool

from app.core.config import Settings
from app.jobs import JobManager
from app.records_io import (
    ACCEPTED_UNITS_DOC,
    UNITS_SYNTAX,
    RecordFormatError,
    csv_body_lines,
    parse_units,
    record_from_csv,
)
from app.services.diagnosis_requests import DiagnosisRequest
from app.services.errors import InvalidInputError
from app.services.sync_diagnosis import SyncDiagnoses
from engine.constants import MAX_SAMPLE_INTERVAL, MIN_SAMPLE_INTERVAL, SAMPLE_INTERVAL
from engine.records import Record
from engine.records.units import BASE_TORQUE
from engine.storage import PatternStore

M = TypeVar("M", bound=BaseModel)


# The accessors of the application's state are coroutines: FastAPI runs a plain function dependency in its
# thread pool, and these need no thread (a hop through the pool per dependency and request, queued behind
# the requests that compute when BACKLASH_REQUEST_THREADS are all busy).
async def get_settings(request: Request) -> Settings:
    return request.app.state.settings


async def get_store(request: Request) -> PatternStore:
    return request.app.state.store


async def get_jobs(request: Request) -> JobManager:
    return request.app.state.jobs


async def get_sync_diagnoses(request: Request) -> SyncDiagnoses:
    return request.app.state.sync_diagnoses


async def get_dask(request: Request) -> Any:
    """The Dask client of ``BACKLASH_DASK_SCHEDULER``'s cluster, or None (jobs run in this process)."""
    return getattr(request.app.state, "dask", None)


SettingsDep = Annotated[Settings, Depends(get_settings)]
DaskDep = Annotated[Any, Depends(get_dask)]
StoreDep = Annotated[PatternStore, Depends(get_store)]
JobsDep = Annotated[JobManager, Depends(get_jobs)]
SyncDiagnosesDep = Annotated[SyncDiagnoses, Depends(get_sync_diagnoses)]


# -- bodies that are JSON or a record's CSV form ---------------------------------------

CSV_MEDIA_TYPES = ("text/csv", "application/csv")


def body_kind(request: Request) -> Literal["json", "csv"]:
    """``json`` or ``csv`` from the Content-Type (no Content-Type means JSON); 415 otherwise."""
    media = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if media in ("", "application/json") or media.endswith("+json"):
        return "json"
    if media in CSV_MEDIA_TYPES:
        return "csv"
    raise HTTPException(
        415,
        f"unsupported Content-Type {media!r}: send the JSON body as application/json, "
        "or the record's CSV form as text/csv",
    )


def json_media(request: Request) -> None:
    """Only JSON bodies (no Content-Type means JSON); 415 otherwise."""
    media = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if media not in ("", "application/json") and not media.endswith("+json"):
        raise HTTPException(
            415, f"unsupported Content-Type {media!r}: send the body as JSON with Content-Type: application/json"
        )


def validate_json(model: type[M], raw: bytes) -> M:
    """``raw`` validated as ``model`` (errors as FastAPI's, located under ``body``); blocking, for a worker thread.

    pydantic's JSON parser refuses nesting deeper than it supports with a ``json_invalid`` error (400), so a
    deeply nested body is answered, never a ``RecursionError``.
    """
    try:
        return model.model_validate_json(raw)
    except ValidationError as exc:
        raise body_errors(exc) from None


async def json_body(request: Request, model: type[M]) -> M:
    """The request body validated as ``model`` (errors as FastAPI's, located under ``body``).

    The body is parsed and validated in a worker thread: a large one must not hold the event loop,
    which serves every other request (``/healthz`` among them) meanwhile.
    """
    raw = await request.body()
    if not raw.strip():
        raise RequestValidationError([{"type": "missing", "loc": ("body",), "msg": "a JSON body is required"}])
    return await run_in_threadpool(validate_json, model, raw)


#: Largest body of the routes whose body is parameters, not a record (simulate, train) [bytes]: a 10 000-case
#: batch with effects is well under 2 MB; a larger body is refused (413) before it is parsed.
PARAMETER_BODY_BYTES = 4 << 20


def json_model(
    model: type[M], max_bytes: int | None = PARAMETER_BODY_BYTES
) -> Callable[[Request], Coroutine[Any, Any, M]]:
    """A dependency that reads the JSON body as ``model`` off the event loop (:func:`json_body`).

    For routes whose body is JSON only; document the body with ``openapi_extra=body_schema(model)``
    (:func:`app.api.openapi.body_schema`), since FastAPI does not see it as a body parameter. A body
    longer than ``max_bytes`` is refused with 413 (``None``: only ``BACKLASH_MAX_BODY_BYTES`` applies).
    """

    def too_large(size: str) -> HTTPException:
        return HTTPException(
            413, f"request body is {size}; the limit of this operation is {max_bytes} bytes: send fewer cases"
        )

    async def read(request: Request) -> M:
        json_media(request)
        declared = request.headers.get("content-length", "")
        if max_bytes is not None and declared.isdigit() and int(declared) > max_bytes:
            raise too_large(f"{int(declared)} bytes")
        if max_bytes is not None and len(await request.body()) > max_bytes:
            raise too_large(f"more than {max_bytes} bytes")
        return await json_body(request, model)

    read.__name__ = f"{model.__name__}_body"
    return read


class CSVRecordParams:
    """Query parameters that complete a record sent in CSV form.

    ``units`` stays text until :func:`csv_record` parses it, so that a JSON body with a
    ``units`` query parameter is told that the parameter belongs to the CSV form.
    """

    def __init__(
        self,
        sample_interval: Annotated[
            float | None,
            Query(
                gt=0,
                allow_inf_nan=False,
                description=f"CSV form: Ts [s], {MIN_SAMPLE_INTERVAL:g} to {MAX_SAMPLE_INTERVAL:g}. Default: the "
                f"step of the CSV's t column, else {SAMPLE_INTERVAL:g}, or the drive's protocol interval when `drive` is "
                "given; given with a t column, the two must agree.",
            ),
        ] = None,
        event_index: Annotated[
            int | None,
            Query(
                ge=0,
                description="CSV form: index of the sample at the event t_e (0 = first data row). Omitted: the "
                "event is located from m_el, else a1 (a record with neither needs it).",
            ),
        ] = None,
        units: Annotated[
            str | None,
            Query(
                description=f"CSV form: units of the channels not in their model unit, as {UNITS_SYNTAX} "
                f"(URL-encoded). Accepted: {ACCEPTED_UNITS_DOC}.",
                examples=["omega1:rpm,a1:g"],
            ),
        ] = None,
        J1: Annotated[float | None, Query(allow_inf_nan=False, description="CSV form: known J1 [kg m^2].")] = None,
        c: Annotated[float | None, Query(allow_inf_nan=False, description="CSV form: known c [pu].")] = None,
        c1: Annotated[float | None, Query(allow_inf_nan=False, description="CSV form: known c1 [pu].")] = None,
        K: Annotated[float | None, Query(allow_inf_nan=False, description="CSV form: known K [m].")] = None,
        base_torque: Annotated[
            float | None,
            Query(allow_inf_nan=False, description="CSV form: the motor's base torque [N*m] (for m_el in N*m)."),
        ] = None,
        asset: Annotated[
            str | None,
            Query(
                description="CSV form: the drive the record came from (letters, digits, '.', '_', '-').",
                examples=["press-7"],
            ),
        ] = None,
        measured_at: Annotated[
            str | None,
            Query(
                description="CSV form: when the record was taken, ISO 8601 with a UTC offset "
                "(e.g. 2026-11-20T08:00:00Z).",
                examples=["2026-11-20T08:00:00Z"],
            ),
        ] = None,
        drive: Annotated[
            str | None,
            Query(
                description="CSV form: the drive the record was measured on, its description as a JSON object "
                "(URL-encoded; the sections of its TOML file, docs/drive-description.md). Omitted: MODEL.md's "
                "reference plant.",
                examples=['{"name": "my drive", "mechanics": {"J2": 0.6}}'],
            ),
        ] = None,
        plant: Annotated[
            str | None,
            Query(
                description="CSV form of an uploaded plant's record: the plant's id (POST /v1/plants); the CSV is "
                "then the plant's (docs/fmu-plant.md), its units in its header, and the backlash drive's parameters "
                "above do not apply.",
                examples=["fmu-0123456789abcdef"],
            ),
        ] = None,
    ) -> None:
        self.sample_interval = sample_interval
        self.plant = plant
        self.event_index = event_index
        self.units_text = units
        self.asset = asset
        self.measured_at = measured_at
        self.drive = drive
        given = {"J1": J1, "c": c, "c1": c1, "K": K, BASE_TORQUE: base_torque}
        self.conditions = {k: v for k, v in given.items() if v is not None}

    def units(self) -> dict[str, str]:
        """The ``units`` query parameter as channel -> unit.

        Raises
        ------
        InvalidInputError
            Malformed (a pair that is not ``CHANNEL:UNIT``, a channel named twice): 422 with the syntax.
        """
        try:
            return parse_units(self.units_text)
        except RecordFormatError as exc:
            raise InvalidInputError(f"query parameter {exc}") from None

    def as_params(self) -> dict[str, Any]:
        """The parameters as a JSON-able dict (how a stored CSV record keeps them)."""
        return {
            "sample_interval": self.sample_interval,
            "event_index": self.event_index,
            "units": self.units_text,
            "conditions": dict(self.conditions),
            "asset": self.asset,
            "measured_at": self.measured_at,
            "drive": self.drive,
            **({"plant": self.plant} if self.plant is not None else {}),
        }


CSVRecordDep = Annotated[CSVRecordParams, Depends()]


async def csv_record(request: Request, params: CSVRecordParams, default_interval: float | None = None) -> Record:
    """The record sent in CSV form (header of channel names, optionally ``t``; one row per sample).

    Decoded and parsed in a worker thread, off the event loop (as :func:`json_body`). ``default_interval`` [s]:
    the Ts of a CSV with neither ``sample_interval`` nor a ``t`` column, the protocol interval of the drive the
    request gives (``DriveDescription.grid().sample_interval``); default MODEL.md's 0.1 ms.
    """
    raw = await request.body()
    units = params.units()

    def read() -> Record:
        return record_from_csv(
            csv_body_lines(raw),
            params.sample_interval,
            params.event_index,
            params.conditions,
            units,
            default_interval=default_interval,
        )

    return await run_in_threadpool(read)


def reject_query(request: Request, names: tuple[str, ...]) -> None:
    """Query parameters meant for the CSV form must not accompany a JSON body."""
    given = [n for n in names if n in request.query_params]
    if given:
        raise InvalidInputError(
            f"query parameter(s) {', '.join(given)} apply only to a record sent as CSV (Content-Type: text/csv); "
            "with a JSON body put them in the body"
        )


#: Query parameters of the CSV form of record bodies.
CSV_QUERY = (
    "sample_interval",
    "event_index",
    "units",
    "J1",
    "c",
    "c1",
    "K",
    BASE_TORQUE,
    "asset",
    "measured_at",
    "drive",
    "plant",
)


async def diagnosis_request(request: Request, params: CSVRecordParams) -> DiagnosisRequest:
    """The diagnosis request as sent (JSON body, or CSV body with its query parameters); 415 for other bodies."""
    kind = body_kind(request)
    raw = await request.body()
    settings: Settings = request.app.state.settings
    store = str(request.app.state.store.path) if settings.allow_fmu_plants else None  # uploaded plants, if on
    if kind == "csv":
        return DiagnosisRequest("csv", raw, params.as_params(), store=store)
    reject_query(request, CSV_QUERY)
    if not raw.strip():
        raise RequestValidationError([{"type": "missing", "loc": ("body",), "msg": "a JSON body is required"}])
    return DiagnosisRequest("json", raw, {}, store=store)


def body_errors(exc: ValidationError) -> RequestValidationError:
    """A body's pydantic errors as FastAPI's (located under ``body``), for the 422 answer."""
    return RequestValidationError(
        [{**e, "loc": ("body", *e["loc"])} for e in exc.errors(include_url=False, include_input=False)]
    )
