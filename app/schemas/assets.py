"""Drives ("assets") and their width history: names, timestamps, history points and the trend."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Literal

from pydantic import AwareDatetime, BaseModel, Field

#: A drive's name as records give it: letters, digits, ``.``, ``_``, ``-`` (it appears in URLs).
ASSET_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$"

AssetName = Annotated[
    str,
    Field(
        pattern=ASSET_PATTERN,
        description="The drive the record came from (letters, digits, '.', '_', '-'; at most 100 characters).",
        examples=["press-7"],
    ),
]
MeasuredAt = Annotated[
    AwareDatetime,
    Field(
        description="When the record was taken: ISO 8601 with a UTC offset (e.g. 2026-11-20T08:00:00Z); "
        "default: when the service received it.",
        examples=["2026-11-20T08:00:00Z"],
    ),
]


class AssetPublic(BaseModel):
    asset: str
    n_identifications: int = Field(description="Stored identifications of the asset.")
    n_diagnoses: int = Field(description="Stored diagnoses of the asset.")
    first_measured_at: datetime | None = None
    last_measured_at: datetime | None = None


class AssetsPublic(BaseModel):
    items: list[AssetPublic]


class HistoryPointPublic(BaseModel):
    measured_at: datetime
    kind: Literal["identification", "diagnosis"]
    id: str = Field(description="The identification's or diagnosis's id.")
    K: float | None = Field(default=None, description="Backlash width found [m] (continuous estimate).")
    K_sigma: float | None = Field(default=None, description="Its 1-sigma uncertainty [m].")
    status: str | None = Field(default=None, description="A diagnosis's verdict status.")
    effect: str | None = Field(default=None, description="A diagnosis's named effect.")
    used_in_trend: bool = Field(description="Whether the trend uses this point (identifications with a width).")


class HistoryPublic(BaseModel):
    asset: str
    points: list[HistoryPointPublic] = Field(
        description="Oldest measurement first: the newest `limit` points (measured before `before`, if given)."
    )
    more: bool = Field(default=False, description="Whether older points exist than these.")
    next_before: datetime | None = Field(
        default=None, description="When `more`: the `before` query that reads the next (older) points."
    )


class TrendPublic(BaseModel):
    asset: str
    limit: float = Field(description="The width limit asked about [m].")
    rate_m_per_day: float = Field(description="Growth rate of the width [m/day].")
    rate_sigma_m_per_day: float = Field(description="Its 1-sigma uncertainty [m/day].")
    crossing_date: datetime | None = Field(description="When the fitted width reaches the limit; null if never.")
    crossing_interval: list[datetime | None] = Field(
        description="[earliest, latest] at the stated confidence; null ends are unbounded."
    )
    confidence: float
    n_points: int
    method: str = Field(description="What was fitted and what it assumes.")
    message: str | None = Field(default=None, description="Why the crossing or an end of its interval is missing.")
    rate_interval_m_per_day: list[float] = Field(description="The rate's interval at the stated confidence [m/day].")
    significant: bool = Field(description="Whether the growth is significantly above zero at that confidence.")
    scatter_factor: float = Field(
        description="Factor applied to the uncertainties for the scatter about the line (>= 1; Birge ratio)."
    )
    dof: int = Field(description="Degrees of freedom of the fit (n_points - 2).")
    width_now_m: float | None = Field(default=None, description="The fitted width today [m].")
    width_now_sigma_m: float | None = Field(default=None, description="Its 1-sigma uncertainty [m].")
