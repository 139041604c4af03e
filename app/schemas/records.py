"""Stored records (the records the service was asked to diagnose)."""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, Field


class RecordPublic(BaseModel):
    id: str
    plant: str
    name: str | None = None
    asset: str | None = None
    measured_at: datetime | None = Field(default=None, description="When the record was taken (or received).")
    n_samples: int
    created_at: datetime
    media: Literal["json", "csv"] = Field(description="How it was sent; GET /v1/records/{id}/body returns it so.")
    params: dict[str, Any] = Field(description="The CSV form's query parameters (empty for JSON).")


class RecordsPublic(BaseModel):
    items: list[RecordPublic] = Field(description="Newest first.")
