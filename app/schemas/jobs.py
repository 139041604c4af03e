"""Background-job responses."""

from __future__ import annotations

from datetime import datetime
from typing import Literal

from pydantic import BaseModel, Field


class JobPublic(BaseModel):
    id: str
    kind: str = Field(description="What the job does, e.g. train_pattern_set.")
    state: Literal["queued", "running", "done", "failed"]
    progress: float = Field(ge=0.0, le=1.0, description="Fraction done, 0..1; never decreases.")
    stage: str | None = Field(default=None, description="What the job is doing now.")
    error: str | None = Field(default=None, description="Why the job failed (state failed only).")
    created_at: datetime
    started_at: datetime | None = None
    finished_at: datetime | None = None
    pattern_set_id: str | None = Field(default=None, description="The pattern set a training job stores.")
