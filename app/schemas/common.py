"""Models shared by several resources: errors, channel names, the record format."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import AllowInfNan, BaseModel, ConfigDict, Field, Strict, StrictInt

from app.records_io import ACCEPTED_UNITS_DOC
from app.schemas.assets import AssetName, MeasuredAt
from engine.constants import (
    CHANNEL_UNITS,
    CHANNELS,
    MAX_SAMPLE_INTERVAL,
    MIN_SAMPLE_INTERVAL,
    POST_EVENT_TIME,
    PRE_EVENT_TIME,
    SAMPLE_INTERVAL,
)
from engine.records import Record, record_from_data
from engine.records.limits import MAX_SAMPLES

if TYPE_CHECKING:
    ChannelName = str
else:
    #: One of the recorded channels of MODEL.md section 3 (validated as a literal, an enum in the OpenAPI schema).
    ChannelName = Literal[CHANNELS]

#: A finite number as JSON writes one (an integer or a decimal), never a string or a boolean: ``false`` or
#: ``"0.005"`` is refused (422), not read as 0 or 0.005.
Number = Annotated[float, Strict(), AllowInfNan(False)]
#: A sample of a record: a number as JSON writes one, never a string or a boolean (NaN and infinities are let
#: through, for the record's reader to say which sample is not finite).
Sample = Annotated[float, Strict()]
#: A series of a record: at most :data:`engine.records.limits.MAX_SAMPLES` samples (stated in the schema as
#: ``maxItems`` and checked as the body is validated, before any record is built; the engine checks it again).
Samples = Annotated[list[Sample], Field(max_length=MAX_SAMPLES)]
#: A series of numbers (never strings or booleans, all finite) of at most ``MAX_SAMPLES`` samples.
NumberSeries = Annotated[list[Number], Field(max_length=MAX_SAMPLES)]


def stated_range(minimum: float | None = None, maximum: float | None = None, *, exclusive: bool = False) -> Any:
    """``Field`` metadata that states a number's accepted range in the schema (``Annotated[Number, ...]``) without
    checking it here: the engine checks it, with a message that names the quantity, its unit and the range.
    ``exclusive``: the minimum itself is not accepted."""
    extra: dict[str, float] = {}
    if minimum is not None:
        extra["exclusiveMinimum" if exclusive else "minimum"] = minimum
    if maximum is not None:
        extra["maximum"] = maximum
    return Field(json_schema_extra=extra)  # type: ignore[arg-type]


#: The simulator's accepted ranges of a case's parameters (engine.simulation.PlantParameters.validate), stated in
#: the schema; tests/app/test_app_hardening.py checks them against the engine.
PLANT_RANGES: dict[str, tuple[float, float]] = {
    "K": (1e-5, 0.05),
    "J1": (0.05, 20.0),
    "c": (0.0, 100.0),
    "c1": (0.0, 100.0),
}
WidthK = Annotated[Number, stated_range(*PLANT_RANGES["K"])]
InertiaJ1 = Annotated[Number, stated_range(*PLANT_RANGES["J1"])]
ViscosityC = Annotated[Number, stated_range(*PLANT_RANGES["c"])]
DiscontinuityC1 = Annotated[Number, stated_range(*PLANT_RANGES["c1"])]
#: A sample interval of a record [s] (engine.records.SampleGrid checks it).
Interval = Annotated[Number, stated_range(MIN_SAMPLE_INTERVAL, MAX_SAMPLE_INTERVAL)]
#: A positive number (checked here: a base torque [N*m] that no conversion uses would not be checked elsewhere).
Positive = Annotated[Number, Field(gt=0)]

_CHANNELS_DOC = ", ".join(f"{c} [{CHANNEL_UNITS[c]}]" for c in CHANNELS)


class ErrorPublic(BaseModel):
    """Every 4xx/5xx answer: ``detail`` says what went wrong and what to fix."""

    detail: str = Field(description="What went wrong and what to fix.")
    error: str = Field(description="Kind of error, e.g. ParameterError, RecordError, RequestValidationError.")
    errors: list[dict[str, Any]] | None = Field(
        default=None, description="For request validation errors: the first offending fields (loc, msg, type)."
    )


class Message(BaseModel):
    message: str


class ConditionsIn(BaseModel):
    """What is known about the operating point; omit what is not known."""

    model_config = ConfigDict(extra="forbid")

    J1: Number | None = Field(default=None, description="Motor-side inertia [kg m^2].")
    c: Number | None = Field(default=None, description="Apparent viscosity of the absorber [pu].")
    c1: Number | None = Field(default=None, description="Absorber discontinuity at zero speed [pu].")
    K: Number | None = Field(default=None, description="Backlash zone width [m] (when known, e.g. simulated).")
    base_torque: Positive | None = Field(
        default=None,
        description="The motor's base torque [N*m]: needed (positive) when m_el is given in N*m, to convert it to pu.",
    )

    def as_dict(self) -> dict[str, float]:
        """The conditions given, by name."""
        return {k: v for k, v in self.model_dump().items() if v is not None}


class DriveProvenanceIn(BaseModel):
    """The drive a record was simulated on, as the simulation writes it (``drive`` of its answer)."""

    fingerprint: str = Field(max_length=64, description="SHA-256 of the drive description's values.")
    description: dict[str, Any] | None = Field(
        default=None,
        description="The description: a diagnosis without a drive of its own runs on it (its fingerprint checked).",
    )


class RecordIn(BaseModel):
    """A backlash-test record in the service's JSON record format, as a bench gives it."""

    model_config = ConfigDict(extra="forbid")

    sample_interval: Interval | None = Field(
        default=None,
        description=f"Ts [s], {MIN_SAMPLE_INTERVAL:g} to {MAX_SAMPLE_INTERVAL:g}. Default: the step of `t` when "
        f"given, else MODEL.md's {SAMPLE_INTERVAL:g}, or the drive's protocol interval when the request gives a "
        "drive; given with `t`, the two must agree.",
    )
    event_index: Annotated[StrictInt, Field(ge=0)] | None = Field(
        default=None,
        description="Index of the sample taken at the event t_e (the motor switched off). Omitted: the event is "
        "located from the data (m_el, else a1; a record with neither needs it) and the answer's record "
        "carries `event_location`.",
    )
    channels: dict[str, Samples] = Field(
        description=f"Non-empty subset of the channels {_CHANNELS_DOC} (in those units unless `units` says "
        f"otherwise); finite numbers, the same number for every channel, covering at least "
        f"{PRE_EVENT_TIME * 1e3:g} ms before the event and {POST_EVENT_TIME * 1e3:g} ms from it on "
        f"(a longer record is fine: analyses read that window of it)."
    )
    units: dict[str, str] | None = Field(
        default=None, description="Unit of each channel not in its model unit; accepted: " + ACCEPTED_UNITS_DOC + "."
    )
    t: Samples | None = Field(
        default=None,
        description="Time of each sample [s] (uniform, increasing; any origin), one per sample: defines the "
        "sample interval.",
    )
    conditions: ConditionsIn | None = Field(default=None, description="Known operating conditions.")
    event_time: Number | None = Field(
        default=None, description="t_e [s] since switch-on, when known (simulated records carry it)."
    )
    asset: AssetName | None = None
    measured_at: MeasuredAt | None = None
    drive: DriveProvenanceIn | None = Field(
        default=None,
        description="The drive a simulated record was made on, as POST /v1/simulate writes it (its fingerprint and "
        "description): it must be the request's drive; a diagnosis request without a drive runs on this one.",
    )

    def to_record(self, default_interval: float | None = None) -> Record:
        """The engine's record, read by :func:`engine.records.record_from_data`.

        Parameters
        ----------
        default_interval : float, optional
            Ts [s] of a record that gives neither ``sample_interval`` nor ``t``: the protocol interval of the
            request's drive when it gives one (``DriveDescription.grid().sample_interval``); default MODEL.md's
            0.1 ms.

        Raises
        ------
        engine.records.RecordError
            Unknown channel or unit, unequal lengths, NaN/inf, a bad time column, or (as
            :class:`~engine.records.ProtocolError`) too little time around the event or an
            event that cannot be located; the message says what to fix.
        """
        return record_from_data(
            channels=self.channels,
            sample_interval=self.sample_interval,
            event_index=self.event_index,
            conditions=self.conditions.as_dict() if self.conditions else {},
            units=self.units or {},
            time=self.t,
            event_time=self.event_time,
            default_interval=default_interval,
        )


class EventLocationPublic(BaseModel):
    """How the event was located in a record that did not give ``event_index``."""

    index: int = Field(description="The first sample at or after the event (the record's event_index).")
    interval: list[float] = Field(
        description="The event lies in (interval[0], interval[1]] relative to that sample [s], i.e. (-Ts, 0]."
    )
    sigma: float = Field(description="Standard uncertainty of the event time [s] (Ts / sqrt(12)).")
    channel: str = Field(description="The channel it was located from (m_el or a1).")
    method: str = Field(description="How, in words.")


class RecordPublic(BaseModel):
    """A record in the JSON record format (the samples in the record's own units)."""

    sample_interval: float = Field(description="Ts [s].")
    event_index: int | None = Field(
        default=None,
        description="Index of the sample taken at the event t_e (absent when the request asked to leave it out: "
        "the reader then locates the event).",
    )
    channels: dict[str, list[float]] = Field(
        description=f"Channels {_CHANNELS_DOC} (in those units unless `units` says otherwise), the same number "
        "of samples each."
    )
    units: dict[str, str] | None = Field(
        default=None, description="Unit of each channel not in its model unit (absent: all in model units)."
    )
    conditions: dict[str, float] = Field(
        description="Operating conditions (J1 [kg m^2], c [pu], c1 [pu], K [m], base_torque [N*m])."
    )
    event_time: float | None = Field(default=None, description="t_e [s] since the motor was switched on.")
    event_location: EventLocationPublic | None = Field(
        default=None, description="How the event was located, when the record did not give event_index."
    )
