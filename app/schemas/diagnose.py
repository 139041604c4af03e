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
    bounds: dict[str, tuple[float, float]] | None = Field(
        default=None,
        description=(
            "Search box of the calibration per parameter, name -> [low, high] in its unit: K [m], J1 [kg m^2], "
            "c [pu], c1 [pu]. Parameters not given keep the default box (K 0.001-0.015 m, J1 0.6-1.2 kg m^2, "
            "c 0.5-2.0 pu, c1 0-0.6 pu); a record's conditions fix a parameter outright."
        ),
        examples=[{"K": [0.002, 0.008], "J1": [0.7, 0.9]}],
    )
