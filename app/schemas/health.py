from __future__ import annotations

from pydantic import BaseModel, Field


class HealthPublic(BaseModel):
    status: str = Field(description="ok")
    version: str = Field(description="Version of the backlash package.")
    model_version: str = Field(description="Reference-model version the engine implements.")
    pattern_sets: int = Field(description="Pattern sets in the store.")
