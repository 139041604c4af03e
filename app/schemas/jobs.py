"""Background-job responses."""

from __future__ import annotations

from datetime import datetime
from typing import Literal

from pydantic import BaseModel, Field

JobStateName = Literal["queued", "running", "done", "failed", "interrupted", "cancelled"]


class JobPublic(BaseModel):
    id: str
    kind: str = Field(description="What the job does: train_pattern_set or diagnose.")
    state: JobStateName = Field(
        description="queued -> running -> done | failed | cancelled; interrupted: the service stopped while the "
        "job was queued or running (POST /v1/jobs/{id}/retry runs it again)."
    )
    progress: float = Field(ge=0.0, le=1.0, description="Fraction done, 0..1; never decreases.")
    stage: str | None = Field(default=None, description="What the job is doing now.")
    error: str | None = Field(default=None, description="Why the job failed, was interrupted or cancelled.")
    created_at: datetime
    started_at: datetime | None = None
    finished_at: datetime | None = None
    pattern_set_id: str | None = Field(default=None, description="The pattern set a training job stores.")
    diagnosis_id: str | None = Field(default=None, description="The diagnosis a diagnosis job computes.")
    retry_of: str | None = Field(default=None, description="The job this one runs again.")


class JobsPublic(BaseModel):
    items: list[JobPublic] = Field(description="Newest first.")
