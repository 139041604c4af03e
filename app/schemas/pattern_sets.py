"""Pattern-set (trained identifier) requests and responses."""

from __future__ import annotations

import inspect
from typing import TYPE_CHECKING, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictInt, model_validator

from app.schemas.common import ChannelName, InertiaJ1, Number, ViscosityC
from app.schemas.drive import DriveIn
from app.schemas.simulate import Effects
from engine.constants import C_GROUPS, C_NOMINAL, J1_GRID
from engine.identification.training import DEFAULT_KIND, IDENTIFIERS

if TYPE_CHECKING:
    IdentifierKind = str
else:
    #: One of the engine's identifier kinds (validated as a literal, listed as an enum in the OpenAPI schema).
    IdentifierKind = Literal[tuple(IDENTIFIERS)]

#: The paper kind's hyper-parameter defaults, read from the identifier itself (documented below, never repeated).
_PAPER_DEFAULTS: dict[str, Any] = {
    name: p.default for name, p in inspect.signature(IDENTIFIERS["paper"]).parameters.items()
}


class PatternSetCreate(BaseModel):
    """Train one pattern set: the six widths x the J1 values at one c, on one channel."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "examples": [
                {"channel": "v2", "c": C_NOMINAL},
                {
                    "channel": "v2",
                    "c": C_NOMINAL,
                    "kind": "paper",
                    "l": _PAPER_DEFAULTS["learning_rate"],
                    "delta1": _PAPER_DEFAULTS["delta1"],
                },
            ]
        },
    )

    channel: ChannelName = Field(description="Channel the identifier works on.")
    c: ViscosityC = Field(
        description="Apparent-viscosity group of the training cases [pu] "
        f"(paper: {', '.join(f'{c:g}' for c in C_GROUPS)})."
    )
    J1_values: list[InertiaJ1] | None = Field(
        default=None,
        min_length=1,
        max_length=32,
        description=f"Motor-side inertias of the training cases [kg m^2]; default the paper's grid {list(J1_GRID)} "
        "(with a drive, scaled to its nominal J1).",
    )
    kind: IdentifierKind = Field(
        default=DEFAULT_KIND, description=f"Identifier kind: {', '.join(IDENTIFIERS)} (default {DEFAULT_KIND})."
    )
    l: Number | None = Field(
        default=None,
        gt=0,
        description=f"paper kind: learning coefficient l [-] (default {_PAPER_DEFAULTS['learning_rate']:g}).",
    )
    delta1: Number | None = Field(
        default=None,
        gt=0,
        description=f"paper kind: training stops at RMS < delta1 [-] (default {_PAPER_DEFAULTS['delta1']:g}).",
    )
    max_epochs: StrictInt | None = Field(
        default=None,
        ge=1,
        le=100_000,
        description=f"paper kind: epoch cap per network (default {_PAPER_DEFAULTS['max_epochs']}).",
    )
    params: dict[str, Any] = Field(
        default_factory=dict,
        description="Further hyper-parameters of the identifier by name (e.g. the template kind's window [samples]).",
    )
    effects: Effects = Field(
        default_factory=dict, description="Unmodelled effects (catalogue name -> value) applied to every training case."
    )
    drive: DriveIn | None = None

    def _named_params(self) -> dict[str, Any]:
        named = {"learning_rate": self.l, "delta1": self.delta1, "max_epochs": self.max_epochs}
        return {k: v for k, v in named.items() if v is not None}

    @model_validator(mode="after")
    def _each_parameter_once(self) -> PatternSetCreate:
        both = sorted(set(self._named_params()) & set(self.params))
        if both:
            raise ValueError(f"give {both} either as fields or in params, not both")
        return self

    def identifier_params(self) -> dict[str, Any]:
        """The identifier's hyper-parameters: ``params`` plus ``l`` (as learning_rate), ``delta1`` and ``max_epochs``."""
        return {**self.params, **self._named_params()}


class TrainingAccepted(BaseModel):
    """A training job was queued; poll ``job_url`` until its state is done or failed."""

    job_id: str
    pattern_set_id: str = Field(description="Id the pattern set will have once the job is done.")
    job_url: str
    pattern_set_url: str


class PatternSetPublic(BaseModel):
    """A stored pattern set (metadata; the arrays are listed by name and shape)."""

    id: str
    kind: str
    channel: str
    c: float = Field(description="Apparent-viscosity group [pu].")
    J1_values: list[float] = Field(description="Inertias of the training cases [kg m^2].")
    wavelet: str
    params: dict[str, Any] = Field(description="Identifier parameters, effects and training outcome.")
    model_version: str
    created_at: str
    arrays: dict[str, list[int]] = Field(description="Stored arrays: name -> shape.")


class PatternSetsPublic(BaseModel):
    data: list[PatternSetPublic]
    count: int
