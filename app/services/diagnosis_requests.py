"""A diagnosis request as the service receives it, read the same way wherever it runs.

The HTTP layer validates a request (:func:`parse`) before it answers, then hands the request as
it was sent (:class:`DiagnosisRequest`: the body's bytes and the CSV form's query parameters)
to a worker process, which reads it again with the same code and computes the diagnosis
(:func:`compute`). Keeping the body as sent means a stored record can be diagnosed again (a
retried job, a record picked in the report page) by exactly the reading that accepted it.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any, Literal

from pydantic import TypeAdapter, ValidationError
from pydantic_core import from_json

from app.records_io import RecordFormatError, csv_body_lines, parse_units, record_from_csv
from app.schemas.assets import AssetName, MeasuredAt
from app.schemas.diagnose import BrfdDiagnoseCreate, DiagnoseCreate, FmuDiagnoseCreate, PlantDiagnoseCreate
from app.services import diagnosis, plant_diagnosis, plants, simulation
from app.services.errors import ForbiddenError, InvalidInputError
from app.services.identification import drive_for_record
from app.services.plant_diagnosis import PlantRecords
from engine.diagnosis.plant_plausibility import check_channels
from engine.diagnosis.space import check_bounds
from engine.plants import DEFAULT_PLANT, get_plant
from engine.plants.fmu.record import load_record
from engine.simulation import CATALOGUE
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription

__all__ = ["DiagnosisOutcome", "DiagnosisRequest", "ParsedDiagnosis", "compute", "parse", "run_sync"]

#: Request schema per plant other than the default.
PLANT_SCHEMAS: dict[str, type[PlantDiagnoseCreate] | type[BrfdDiagnoseCreate]] = {
    "emps": PlantDiagnoseCreate,
    "brfd": BrfdDiagnoseCreate,
}

_ASSET = TypeAdapter(AssetName)
_MEASURED_AT = TypeAdapter(MeasuredAt)


@dataclass(frozen=True)
class DiagnosisRequest:
    """A diagnosis request as sent.

    Attributes
    ----------
    media : {"json", "csv"}
        The body's form.
    body : bytes
        The body as received.
    params : dict
        The CSV form's query parameters (``sample_interval``, ``event_index``, ``units``,
        ``conditions``, ``asset``, ``measured_at``, ``drive``, ``plant``); empty for JSON.
    store : str, optional
        The store whose uploaded plants (``fmu-...``, :mod:`app.services.plants`) the request may name;
        ``None`` where FMU plants are off (a request naming one is refused). Not part of what is stored.
    """

    media: Literal["json", "csv"]
    body: bytes
    params: dict[str, Any] = field(default_factory=dict)
    store: str | None = None


@dataclass(frozen=True)
class ParsedDiagnosis:
    """What a request asks for, read and checked (nothing computed yet)."""

    plant: str
    record: Any
    calibrate_on: Any | None = None
    hold: bool = False
    effects: list[str] | None = None
    bounds: dict[str, tuple[float, float]] | None = None
    asset: str | None = None
    measured_at: datetime | None = None
    name: str | None = None
    drive: DriveDescription | None = None
    resolved: Any = None  # the plant object of a stored (uploaded) plant, loaded while the request was read


@dataclass(frozen=True)
class DiagnosisOutcome:
    """A computed diagnosis: the answer, its figures (PNG bytes by name) and the summary a drive's history keeps.

    Attributes
    ----------
    width, width_sigma : float or None
        The backlash width the diagnosis found [m] and its 1-sigma uncertainty, where the plant has
        one and the record did not fix it.
    """

    result: dict[str, Any]
    figures: dict[str, bytes]
    status: str | None
    effect: str | None
    width: float | None
    width_sigma: float | None


def named_plant(raw: bytes) -> str | None:
    """The plant a JSON body names when it is not the default one (malformed bodies are left to the validation).

    Read with pydantic's JSON parser, which refuses nesting deeper than the validation supports (a
    ``ValueError``, left to the validation's 400 like any malformed body) where ``json.loads`` would raise
    ``RecursionError``.
    """
    if b'"plant"' not in raw and b"\\u" not in raw:  # a body without the key (escaped or not) names none: no parse
        return None  # (parsing a 20 MB body twice would hold the GIL, and the event loop, for twice as long)
    try:
        body = from_json(raw)
    except ValueError:
        return None
    if isinstance(body, dict) and body.get("plant", DEFAULT_PLANT) != DEFAULT_PLANT:
        return str(body.get("plant"))
    return None


def parse(request: DiagnosisRequest) -> ParsedDiagnosis:
    """Read and check a request without computing anything.

    Raises
    ------
    pydantic.ValidationError
        A JSON body that does not fit its schema (the HTTP layer answers 422 with the fields).
    RecordFormatError, engine.records.RecordError, InvalidInputError, UnknownEffectError, BoundsError
        A record or parameter the diagnosis cannot use (a plant's record with a channel that never
        changes among them); the message says what to fix.
    """
    parsed = _parse(request)
    if parsed.plant != DEFAULT_PLANT:  # what the diagnosis would refuse, refused before anything is stored
        plant = parsed.resolved if parsed.resolved is not None else get_plant(parsed.plant)
        for record in (parsed.record, parsed.calibrate_on):
            if record is not None:
                check_channels(plant, record)
    return parsed


def _parse(request: DiagnosisRequest) -> ParsedDiagnosis:
    """:func:`parse` before the plant's channel check."""
    if request.media == "csv":
        if request.params.get("plant") is not None:
            return _parse_stored_csv(request)
        return _parse_csv(request.body, request.params)
    other = named_plant(request.body)
    if plants.is_stored_plant(other):
        plant = _stored_plant(request, str(other))
        fmu_body = FmuDiagnoseCreate.model_validate_json(request.body)
        return ParsedDiagnosis(
            plant=fmu_body.plant,
            record=fmu_body.record.to_record(plant.description),
            calibrate_on=fmu_body.calibrate_on.to_record(plant.description) if fmu_body.calibrate_on else None,
            hold=fmu_body.hold_calibration,
            asset=fmu_body.record.asset,
            measured_at=fmu_body.record.measured_at,
            name=fmu_body.record.name,
            resolved=plant,
        )
    if other is not None:
        if other.startswith("fmu") and other not in PLANT_SCHEMAS:  # not a stored plant's id: the id's pattern (422)
            FmuDiagnoseCreate.model_validate_json(request.body)
        schema = PLANT_SCHEMAS.get(other, PlantDiagnoseCreate)  # an unknown name: the schema's 422
        plant_body = schema.model_validate_json(request.body)
        return ParsedDiagnosis(
            plant=plant_body.plant,
            record=plant_body.record.to_record(),
            calibrate_on=plant_body.calibrate_on.to_record() if plant_body.calibrate_on else None,
            hold=plant_body.hold_calibration,
            asset=plant_body.record.asset,
            measured_at=plant_body.record.measured_at,
            name=plant_body.record.name,
        )
    body = DiagnoseCreate.model_validate_json(request.body)
    for name in body.effects or ():
        CATALOGUE[name]  # UnknownEffectError (422) names the known effects
    stated = None if body.record.drive is None else body.record.drive.model_dump()
    # the request's drive, else the one the record states in full; ParameterError / IncompatibleError (422) say
    # what to fix
    drive = drive_for_record(simulation.drive_of(body.drive), stated)
    check_bounds(body.bounds, drive or REFERENCE_DRIVE)  # BoundsError (422) says what to fix before any work
    record = body.record.to_record(simulation.record_interval(drive))  # without Ts or t: the drive's protocol's
    simulation.check_units(record.units, drive)  # omega1 in pu would be read with MODEL.md's base speed
    return ParsedDiagnosis(
        plant=DEFAULT_PLANT,
        record=record,
        effects=body.effects,
        bounds=body.bounds,
        asset=body.record.asset,
        measured_at=body.record.measured_at,
        drive=drive,
    )


def _stored_plant(request: DiagnosisRequest, plant_id: str) -> Any:
    """The uploaded plant a request names (:func:`app.services.plants.load`); refused where FMU plants are off."""
    if request.store is None:
        raise ForbiddenError(f"plant {plant_id!r}: {plants.OFF_MESSAGE}")
    return plants.load(request.store, plant_id)


#: The CSV form's query parameters that belong to the backlash drive's records (not to an uploaded plant's).
DRIVE_CSV_PARAMS = ("sample_interval", "event_index", "units", "drive")


def _parse_stored_csv(request: DiagnosisRequest) -> ParsedDiagnosis:
    """A record of an uploaded plant in its CSV form (``plant`` query parameter; the CSV as for ``--plant``)."""
    params = request.params
    plant_id = str(params["plant"])
    if not plants.is_stored_plant(plant_id):
        raise InvalidInputError(
            f"query parameter plant {plant_id[:100]!r}: the CSV form names an uploaded plant by its id (fmu- and 16 "
            "hex digits, POST /v1/plants); the backlash drive's CSV needs no plant, and emps and brfd records are "
            "sent as JSON"
        )
    given = [k for k in DRIVE_CSV_PARAMS if params.get(k) is not None] + (
        ["J1/c/c1/K"] if params.get("conditions") else []
    )
    if given:
        raise InvalidInputError(
            f"query parameter(s) {', '.join(given)} belong to the backlash drive's CSV form; a record of plant "
            f"{plant_id} states its units in its header (e.g. 'a_body [m/s2]') and its time in its time column"
        )
    asset, measured_at = named_asset(params.get("asset"), params.get("measured_at"))
    plant = _stored_plant(request, plant_id)
    record = load_record(request.body, plant.description, name=asset or "record")
    return ParsedDiagnosis(
        plant=plant_id, record=record, asset=asset, measured_at=measured_at, name=record.name, resolved=plant
    )


def _parse_csv(raw: bytes, params: dict[str, Any]) -> ParsedDiagnosis:
    asset, measured_at = named_asset(params.get("asset"), params.get("measured_at"))
    lines = csv_body_lines(raw)  # the body is not decoded whole: a long record is read as it is parsed
    try:
        units = parse_units(params.get("units"))
    except RecordFormatError as exc:
        raise InvalidInputError(f"query parameter {exc}") from None
    drive = simulation.drive_from_query(params.get("drive"))  # before the body: a refused description reads nothing
    record = record_from_csv(  # without sample_interval or a t column: read at the drive's protocol interval
        lines,
        params.get("sample_interval"),
        params.get("event_index"),
        params.get("conditions") or {},
        units,
        default_interval=simulation.record_interval(drive),
    )
    simulation.check_units(record.units, drive)  # omega1 in pu would be read with MODEL.md's base speed
    return ParsedDiagnosis(plant=DEFAULT_PLANT, record=record, asset=asset, measured_at=measured_at, drive=drive)


def named_asset(asset: str | None, measured_at: str | None) -> tuple[str | None, datetime | None]:
    """The CSV form's ``asset`` and ``measured_at`` query parameters, checked (``InvalidInputError`` says what to fix)."""
    try:
        name = None if asset is None else _ASSET.validate_python(asset)
    except ValidationError:
        raise InvalidInputError(
            f"query parameter asset {asset!r}: use letters, digits, '.', '_', '-' (at most 100 characters)"
        ) from None
    try:
        when = None if measured_at is None else _MEASURED_AT.validate_python(measured_at)
    except ValidationError as exc:
        raise InvalidInputError(
            f"query parameter measured_at {measured_at!r}: {exc.errors()[0]['msg']}; give ISO 8601 with a UTC "
            "offset, e.g. 2026-11-20T08:00:00Z"
        ) from None
    return name, when


def n_samples(record: Any) -> int:
    """Samples of a record of any plant (of the record as read, for the drive's excerpt of a long one)."""
    origin = getattr(record, "origin", None)
    if origin is not None:
        return int(origin.n_samples)
    for attr in ("t", "time"):
        value = getattr(record, attr, None)
        if value is not None and hasattr(value, "__len__"):
            return len(value)
    grid = getattr(record, "grid", None)
    return int(getattr(grid, "n_samples", 0) or 0)


def compute(
    parsed: ParsedDiagnosis, *, figures: bool = True, progress: Callable[[float, str], None] | None = None
) -> DiagnosisOutcome:
    """Diagnose the record (and draw its figures, PNG, when ``figures``); ``progress(fraction, stage)`` hears of
    the stages (the backlash drive's diagnosis reports them; the plants' diagnoses do not)."""
    pngs: dict[str, bytes] = {}
    with tempfile.TemporaryDirectory(prefix="backlash-figures-") as tmp:
        out_dir = Path(tmp)
        if parsed.plant == DEFAULT_PLANT:
            result = diagnosis.run(parsed.record, parsed.effects, parsed.bounds, progress=progress, drive=parsed.drive)
            answer = result.to_dict()
            if parsed.drive is not None:  # the drive it was diagnosed on, kept with the diagnosis
                answer["drive"] = parsed.drive.provenance()
            if figures and progress is not None:
                progress(1.0, "drawing the figures")
            paths = diagnosis.write_plots(parsed.record, result, out_dir) if figures else []
            shown = answer.get("width") or {}  # the width of the model the answer ends with
            width = shown.get("K") if shown.get("identifiable") else None
            sigma = shown.get("sigma_K") if shown.get("identifiable") else None
        else:
            plant = parsed.resolved if parsed.resolved is not None else get_plant(parsed.plant)
            records = PlantRecords(plant, parsed.record, parsed.calibrate_on)
            plant_result = plant_diagnosis.run(records, parsed.hold)
            answer = plant_result.to_dict()
            paths = plant_diagnosis.write_plots(plant_result, out_dir) if figures else []
            width, sigma = _effect_value(answer, "backlash")
        for path in paths:
            pngs[path.stem] = path.read_bytes()
    verdict = answer.get("verdict") or {}
    return DiagnosisOutcome(
        result=answer,
        figures=pngs,
        status=verdict.get("status") or answer.get("status"),
        effect=verdict.get("effect"),
        width=_finite(width),
        width_sigma=_finite(sigma),
    )


def _effect_value(answer: dict[str, Any], effect: str) -> tuple[Any, Any]:
    for row in (answer.get("verdict") or {}).get("effects") or ():
        if isinstance(row, dict) and row.get("effect") == effect:
            return row.get("value"), row.get("uncertainty")
    return None, None


def _finite(value: Any) -> float | None:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if number == number and abs(number) != float("inf") else None


def run_sync(request: DiagnosisRequest) -> dict[str, Any]:
    """The synchronous ``POST /v1/diagnose``'s work in a worker process: read, diagnose, answer (no figures)."""
    return compute(parse(request), figures=False).result
