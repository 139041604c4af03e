"""Simulation requests and responses."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, StrictBool, field_validator

from app.core.config import MAX_BATCH_CASES_LIMIT
from app.records_io import ACCEPTED_UNITS_DOC
from app.schemas.common import (
    ChannelName,
    DiscontinuityC1,
    InertiaJ1,
    Interval,
    Number,
    Positive,
    RecordPublic,
    ViscosityC,
    WidthK,
    stated_range,
)
from app.schemas.drive import DriveIn, DrivePublic
from app.services.simulation import MAX_RENDERED_SAMPLES, SIMULATED_EFFECTS, Rendering
from engine.constants import (
    C1_NOMINAL,
    C_NOMINAL,
    J1_NOMINAL,
    K_GRID,
    K_NOMINAL,
    MAX_SAMPLE_INTERVAL,
    MIN_SAMPLE_INTERVAL,
    POST_EVENT_TIME,
    PRE_EVENT_TIME,
    SAMPLE_INTERVAL,
)
from engine.records.grid import GridError, SampleGrid

_EFFECTS_DOC = (
    'Unmodelled effects by catalogue name and value, e.g. {"motor_coulomb_friction": 0.02}; see the '
    "effects catalogue (engine.simulation.CATALOGUE) and the held-back family (engine.simulation.HELD_BACK: "
    "effects outside the diagnosis's catalogue) for names, meanings and ranges."
)

#: Longest span rendered before or after the event [s]: the most samples a request renders, at the longest
#: interval (a bound against spans whose sample count does not fit a number; shorter spans are checked
#: against MAX_RENDERED_SAMPLES when rendered).
MAX_SPAN = MAX_RENDERED_SAMPLES * MAX_SAMPLE_INTERVAL


def _effects_schema() -> dict[str, object]:
    """The simulator's effects (catalogue and held-back family) by name, each with its range and unit, stated in
    the schema; the engine checks names and values (its message lists the known effects)."""
    return {
        "properties": {
            e.name: {"type": "number", "minimum": e.bounds[0], "maximum": e.bounds[1], "description": f"[{e.unit}]"}
            for e in SIMULATED_EFFECTS.values()
        },
        "additionalProperties": False,
    }


#: Unmodelled effects of a simulated case: name -> value, the names and ranges stated in the schema.
Effects = Annotated[dict[str, Number], Field(json_schema_extra=_effects_schema())]


class SimulateCase(BaseModel):
    """One case of the backlash test; omitted values take MODEL.md's defaults."""

    model_config = ConfigDict(extra="forbid")

    K: WidthK = Field(description=f"Backlash zone width [m] (paper grid {K_GRID[0]:g} .. {K_GRID[-1]:g}).")
    J1: InertiaJ1 | None = Field(default=None, description=f"Motor-side inertia [kg m^2]; default {J1_NOMINAL:g}.")
    c: ViscosityC | None = Field(
        default=None, description=f"Apparent viscosity of the absorber [pu]; default {C_NOMINAL:g}."
    )
    c1: DiscontinuityC1 | None = Field(
        default=None, description=f"Absorber discontinuity at zero speed [pu]; default {C1_NOMINAL:g}."
    )
    effects: Effects = Field(default_factory=dict, description=_EFFECTS_DOC)


class RenderIn(BaseModel):
    """How the simulated records are rendered, the ways a test bench gives them; defaults: MODEL.md's record."""

    model_config = ConfigDict(extra="forbid")

    sample_interval: Interval = Field(
        default=SAMPLE_INTERVAL,
        description=f"Ts [s] of the rendered record, {MIN_SAMPLE_INTERVAL:g} to {MAX_SAMPLE_INTERVAL:g}.",
    )
    before: Annotated[Number, stated_range(PRE_EVENT_TIME)] = Field(
        default=PRE_EVENT_TIME,
        le=MAX_SPAN,
        description=f"Time rendered before the event [s]; at least {PRE_EVENT_TIME * 1e3:g} ms (MODEL.md's window), "
        f"at most {MAX_SPAN:g} s.",
    )
    after: Annotated[Number, stated_range(POST_EVENT_TIME)] = Field(
        default=POST_EVENT_TIME,
        le=MAX_SPAN,
        description=f"Time rendered from the event on [s]; at least {POST_EVENT_TIME * 1e3:g} ms (MODEL.md's "
        f"window), at most {MAX_SPAN:g} s.",
    )
    units: dict[ChannelName, str] = Field(
        default_factory=dict,
        description="Unit to write each channel in (the others in their model units); accepted: "
        + ACCEPTED_UNITS_DOC
        + ". m_el in N*m needs base_torque.",
    )
    channels: list[ChannelName] | None = Field(
        default=None, min_length=1, description="Channels to keep (default all five)."
    )
    include_event_index: StrictBool = Field(
        default=True,
        description="false leaves event_index out of the answer (and the X-Event-Index header of the CSV form): "
        "the reader has to locate the event from the data, as with a bench record.",
    )
    base_torque: Positive | None = Field(
        default=None,
        description="The motor's base torque [N*m], stated in the record's conditions; needed for m_el in N*m.",
    )

    @field_validator("sample_interval")
    @classmethod
    def _check_sample_interval(cls, value: float) -> float:
        """Refuse an interval outside 10 us - 1 ms here, with the engine's message, before any span is divided by it."""
        try:
            SampleGrid(sample_interval=value, n_samples=2, event_index=0)
        except GridError as exc:
            raise ValueError(str(exc)) from None
        return value

    def rendering(self, span: dict[str, float] | None = None) -> Rendering:
        """The service's :class:`~app.services.simulation.Rendering` of these options.

        ``span`` gives ``sample_interval``, ``before`` and ``after`` [s] where the request leaves them out (a drive's
        protocol: :func:`app.services.simulation.protocol_span`); default MODEL.md's.
        """
        given = {k: getattr(self, k) for k in ("sample_interval", "before", "after")}
        if span is not None:
            given.update({k: v for k, v in span.items() if k not in self.model_fields_set})
        return Rendering(
            **given,
            units=dict(self.units),
            channels=None if self.channels is None else list(self.channels),
            include_event_index=self.include_event_index,
            base_torque=self.base_torque,
        )


class SimulateCreate(SimulateCase, RenderIn):
    """One case of the backlash test, rendered as asked; omitted values take MODEL.md's defaults."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "examples": [
                {"K": K_NOMINAL, "J1": J1_NOMINAL, "c": C_NOMINAL, "c1": C1_NOMINAL, "effects": {}},
                {
                    "K": K_NOMINAL,
                    "sample_interval": 5e-5,
                    "before": 0.01,
                    "after": 0.3,
                    "units": {"omega1": "rpm", "a1": "g"},
                    "include_event_index": False,
                },
            ]
        },
    )

    drive: DriveIn | None = None

    time_column: StrictBool = Field(
        default=False,
        description="CSV form (Accept: text/csv): add a first column t, the time of each sample [s] from the "
        "first sample, which carries the sample interval.",
    )


class SimulateBatchCreate(RenderIn):
    """Several cases simulated in one call (at most BACKLASH_MAX_BATCH_CASES), all rendered the same way."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "examples": [
                {
                    "cases": [{"K": K_GRID[0]}, {"K": K_NOMINAL, "J1": J1_NOMINAL, "effects": {}}],
                    "sample_interval": 2e-4,
                    "channels": ["a2", "v2"],
                    "units": {"a2": "g"},
                }
            ]
        },
    )

    drive: DriveIn | None = None

    cases: list[SimulateCase] = Field(
        min_length=1,
        max_length=MAX_BATCH_CASES_LIMIT,
        description="The cases, simulated in this order (at most BACKLASH_MAX_BATCH_CASES, which is at most "
        f"{MAX_BATCH_CASES_LIMIT}).",
    )

    @field_validator("cases", mode="before")
    @classmethod
    def _count_cases(cls, value: object) -> object:
        """Refuse too many cases before validating each (a huge list of models would hold the interpreter)."""
        if isinstance(value, list) and len(value) > MAX_BATCH_CASES_LIMIT:
            raise ValueError(
                f"the batch has {len(value)} cases; the service allows at most BACKLASH_MAX_BATCH_CASES, which is "
                f"at most {MAX_BATCH_CASES_LIMIT}: split it into several requests"
            )
        return value


class SimulationPublic(RecordPublic):
    """The simulated record; ``conditions`` carry its J1, c, c1 and K, ``event_time`` is t_e."""

    event_time: float = Field(description="t_e [s] since the motor was switched on.")
    drive: DrivePublic | None = Field(
        default=None, description="The drive description it was simulated on, when the request gave one."
    )


class SimulationsPublic(BaseModel):
    data: list[SimulationPublic]
    count: int
