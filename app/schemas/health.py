from __future__ import annotations

from pydantic import BaseModel, Field


class HealthPublic(BaseModel):
    """The service's health; without the API key (when the service has one) only ``status``."""

    status: str = Field(description="ok")
    version: str | None = Field(
        default=None, description="Version of the backlash package (absent without the API key, when one is set)."
    )
    model_version: str | None = Field(
        default=None,
        description="Reference-model version the engine implements (absent without the API key, when one is set).",
    )
    pattern_sets: int | None = Field(
        default=None, description="Pattern sets in the store (absent without the API key, when one is set)."
    )
