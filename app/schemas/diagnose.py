"""Diagnosis request (the response is defined by the diagnosis issue)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from app.schemas.common import RecordIn


class DiagnoseCreate(BaseModel):
    """Diagnose the gap between a measured record and the model."""

    model_config = ConfigDict(extra="forbid")

    record: RecordIn
    effects: list[str] | None = Field(
        default=None, description="Candidate effects (catalogue names) to consider; default the whole catalogue."
    )
