"""Maintenance responses: what a retention run deleted and how the database file's size changed."""

from __future__ import annotations

from datetime import datetime
from typing import Literal

from pydantic import BaseModel, Field


class DeletedPublic(BaseModel):
    jobs: int = Field(description="Finished jobs deleted.")
    diagnoses: int = Field(description="Diagnoses deleted (their jobs had finished).")
    figures: int = Field(description="Figures deleted with their diagnoses.")
    records: int = Field(description="Records deleted that no diagnosis or job named any more.")
    identifications: int = Field(description="Identifications deleted.")


class RetentionPublic(BaseModel):
    retention_days: float | None = Field(
        description="The age limit applied [days] (BACKLASH_RETENTION_DAYS); null: nothing is deleted by age."
    )
    cutoff: datetime | None = Field(description="Rows stored (jobs: finished) before this instant were deleted.")
    deleted: DeletedPublic
    compaction: Literal["incremental_vacuum", "vacuum", "none"] | None = Field(
        description="How freed pages went back to the file system: incremental_vacuum, vacuum (the one rewrite of "
        "a file made before incremental vacuuming), none (no free page); null: not asked to compact."
    )
    free_pages_before: int | None = Field(description="Free pages inside the file before the compaction.")
    bytes_before: int = Field(description="Database file plus its -wal file before the run [bytes].")
    bytes_after: int = Field(description="The same after the run [bytes].")
    bytes_freed: int = Field(description="bytes_before - bytes_after [bytes].")
    seconds: float = Field(description="Duration of the run [s].")
