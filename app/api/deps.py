"""Dependencies of the routes: settings, the pattern store, the job manager, record bodies."""

from __future__ import annotations

from typing import Annotated, Any, Literal, TypeVar

from fastapi import Depends, HTTPException, Query, Request
from fastapi.exceptions import RequestValidationError
from pydantic import BaseModel, ValidationError

from app.core.config import Settings
from app.jobs import JobManager
from app.records_io import (
    ACCEPTED_UNITS_DOC,
    UNITS_SYNTAX,
    RecordFormatError,
    decode_csv_body,
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


def get_settings(request: Request) -> Settings:
    return request.app.state.settings


def get_store(request: Request) -> PatternStore:
    return request.app.state.store


def get_jobs(request: Request) -> JobManager:
    return request.app.state.jobs


def get_sync_diagnoses(request: Request) -> SyncDiagnoses:
    return request.app.state.sync_diagnoses


def get_dask(request: Request) -> Any:
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


async def json_body(request: Request, model: type[M]) -> M:
    """The request body validated as ``model`` (errors as FastAPI's, located under ``body``)."""
    raw = await request.body()
    if not raw.strip():
        raise RequestValidationError([{"type": "missing", "loc": ("body",), "msg": "a JSON body is required"}])
    try:
        return model.model_validate_json(raw)
    except ValidationError as exc:
        raise body_errors(exc) from None


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
                f"step of the CSV's t column, else {SAMPLE_INTERVAL:g}; given with a t column, the two must agree.",
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
    ) -> None:
        self.sample_interval = sample_interval
        self.event_index = event_index
        self.units_text = units
        self.asset = asset
        self.measured_at = measured_at
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
        }


CSVRecordDep = Annotated[CSVRecordParams, Depends()]


async def csv_record(request: Request, params: CSVRecordParams) -> Record:
    """The record sent in CSV form (header of channel names, optionally ``t``; one row per sample)."""
    text = decode_csv_body(await request.body())
    return record_from_csv(text, params.sample_interval, params.event_index, params.conditions, params.units())


def reject_query(request: Request, names: tuple[str, ...]) -> None:
    """Query parameters meant for the CSV form must not accompany a JSON body."""
    given = [n for n in names if n in request.query_params]
    if given:
        raise InvalidInputError(
            f"query parameter(s) {', '.join(given)} apply only to a record sent as CSV (Content-Type: text/csv); "
            "with a JSON body put them in the body"
        )


#: Query parameters of the CSV form of record bodies.
CSV_QUERY = ("sample_interval", "event_index", "units", "J1", "c", "c1", "K", BASE_TORQUE, "asset", "measured_at")


async def diagnosis_request(request: Request, params: CSVRecordParams) -> DiagnosisRequest:
    """The diagnosis request as sent (JSON body, or CSV body with its query parameters); 415 for other bodies."""
    kind = body_kind(request)
    raw = await request.body()
    if kind == "csv":
        return DiagnosisRequest("csv", raw, params.as_params())
    reject_query(request, CSV_QUERY)
    if not raw.strip():
        raise RequestValidationError([{"type": "missing", "loc": ("body",), "msg": "a JSON body is required"}])
    return DiagnosisRequest("json", raw, {})


def body_errors(exc: ValidationError) -> RequestValidationError:
    """A body's pydantic errors as FastAPI's (located under ``body``), for the 422 answer."""
    return RequestValidationError(
        [{**e, "loc": ("body", *e["loc"])} for e in exc.errors(include_url=False, include_input=False)]
    )
