"""Pattern-set (trained identifier) requests and responses."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, FiniteFloat

from app.schemas.common import ChannelName
from app.services.errors import InvalidInputError
from app.services.patterns import DEFAULT_KIND, IDENTIFIER_KINDS
from engine.constants import J1_GRID

IdentifierKind = Literal[tuple(IDENTIFIER_KINDS)]  # type: ignore[valid-type]


class PatternSetCreate(BaseModel):
    """Train one pattern set: the six widths x the J1 values at one c, on one channel."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "examples": [
                {"channel": "v2", "c": 1.0},
                {"channel": "v2", "c": 1.0, "kind": "paper", "l": 0.9, "delta1": 0.08},
            ]
        },
    )

    channel: ChannelName = Field(description="Channel the identifier works on.")
    c: FiniteFloat = Field(
        description="Apparent-viscosity group of the training cases [pu] (paper: 0.8, 1.0, 1.25, 1.4)."
    )
    J1_values: list[FiniteFloat] | None = Field(
        default=None,
        min_length=1,
        max_length=32,
        description=f"Motor-side inertias of the training cases [kg m^2]; default the paper's grid {list(J1_GRID)}.",
    )
    kind: IdentifierKind = Field(
        default=DEFAULT_KIND, description=f"Identifier kind: {', '.join(IDENTIFIER_KINDS)} (default {DEFAULT_KIND})."
    )
    l: FiniteFloat | None = Field(
        default=None, gt=0, description="paper kind: learning coefficient l [-] (default 0.9)."
    )
    delta1: FiniteFloat | None = Field(
        default=None, gt=0, description="paper kind: training stops at RMS < delta1 [-] (default 0.08)."
    )
    max_epochs: int | None = Field(
        default=None, ge=1, le=100_000, description="paper kind: epoch cap per network (default 2000)."
    )
    params: dict[str, Any] = Field(
        default_factory=dict,
        description="Further hyper-parameters of the identifier by name (e.g. the template kind's window [samples]).",
    )
    effects: dict[str, FiniteFloat] = Field(
        default_factory=dict, description="Unmodelled effects (catalogue name -> value) applied to every training case."
    )


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


def identifier_params(body: PatternSetCreate) -> dict[str, Any]:
    """The identifier's hyper-parameters: ``params`` plus ``l`` (as learning_rate), ``delta1`` and ``max_epochs``."""
    named = {"learning_rate": body.l, "delta1": body.delta1, "max_epochs": body.max_epochs}
    named = {k: v for k, v in named.items() if v is not None}
    both = sorted(set(named) & set(body.params))
    if both:
        raise InvalidInputError(f"give {both} either as fields or in params, not both")
    return {**body.params, **named}
