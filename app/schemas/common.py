"""Models shared by several resources: errors, channel names, the record format."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, FiniteFloat

from engine.constants import CHANNEL_UNITS, CHANNELS, EVENT_INDEX, N_SAMPLES, SAMPLE_INTERVAL
from engine.records import Record

if TYPE_CHECKING:
    ChannelName = str
else:
    #: One of the recorded channels of MODEL.md section 3 (validated as a literal, an enum in the OpenAPI schema).
    ChannelName = Literal[CHANNELS]

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

    J1: FiniteFloat | None = Field(default=None, description="Motor-side inertia [kg m^2].")
    c: FiniteFloat | None = Field(default=None, description="Apparent viscosity of the absorber [pu].")
    c1: FiniteFloat | None = Field(default=None, description="Absorber discontinuity at zero speed [pu].")
    K: FiniteFloat | None = Field(default=None, description="Backlash zone width [m] (when known, e.g. simulated).")

    def as_dict(self) -> dict[str, float]:
        return {k: v for k, v in self.model_dump().items() if v is not None}


class RecordIn(BaseModel):
    """A backlash-test record in the service's JSON record format."""

    model_config = ConfigDict(extra="forbid")

    sample_interval: FiniteFloat = Field(default=SAMPLE_INTERVAL, description="Ts [s].")
    event_index: int = Field(default=EVENT_INDEX, description="Index of the sample taken at the event t_e.")
    channels: dict[str, list[float]] = Field(
        description=f"Non-empty subset of the channels {_CHANNELS_DOC}; each exactly {N_SAMPLES} finite numbers."
    )
    conditions: ConditionsIn | None = Field(default=None, description="Known operating conditions.")
    event_time: FiniteFloat | None = Field(
        default=None, description="t_e [s] since switch-on, when known (simulated records carry it)."
    )

    def to_record(self) -> Record:
        """The engine's record; raises ``RecordError`` (wrong length, NaN/inf, unknown channel, ...)."""
        return Record(
            channels={name: np.asarray(values, dtype=float) for name, values in self.channels.items()},
            sample_interval=self.sample_interval,
            event_index=self.event_index,
            conditions=self.conditions.as_dict() if self.conditions else {},
            event_time=self.event_time,
        )


class RecordPublic(BaseModel):
    """A record in the JSON record format."""

    sample_interval: float = Field(description="Ts [s].")
    event_index: int = Field(description="Index of the sample taken at the event t_e.")
    channels: dict[str, list[float]] = Field(description=f"Channels {_CHANNELS_DOC}, {N_SAMPLES} samples each.")
    conditions: dict[str, float] = Field(description="Operating conditions (J1 [kg m^2], c [pu], c1 [pu], K [m]).")
    event_time: float | None = Field(default=None, description="t_e [s] since the motor was switched on.")
