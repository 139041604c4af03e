"""Drives ("assets"): list them, read a drive's width history and its trend towards a limit."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, Query, Response
from fastapi import Path as PathParam
from pydantic import AwareDatetime
from starlette.concurrency import run_in_threadpool

from app.api.deps import SettingsDep, StoreDep
from app.core.config import MAX_HISTORY_POINTS
from app.schemas.assets import ASSET_PATTERN, AssetPublic, AssetsPublic, HistoryPointPublic, HistoryPublic, TrendPublic
from app.schemas.common import ErrorPublic
from app.services import assets as asset_service

router = APIRouter(prefix="/assets", tags=["assets"])

AssetPath = Annotated[str, PathParam(pattern=ASSET_PATTERN, description="The asset's name.")]
LimitQuery = Annotated[float, Query(gt=0, le=1.0, allow_inf_nan=False, description="The width limit [m], e.g. 0.009.")]
_NOT_FOUND: dict[int | str, dict[str, Any]] = {404: {"model": ErrorPublic, "description": "No such asset"}}


@router.get("", response_model=AssetsPublic, summary="List the assets with stored identifications or diagnoses")
def list_assets(store: StoreDep) -> Any:
    return AssetsPublic(items=[AssetPublic(**a) for a in asset_service.assets(store)])


@router.get("/{asset}/history", response_model=HistoryPublic, summary="An asset's width history", responses=_NOT_FOUND)
def read_history(
    asset: AssetPath,
    store: StoreDep,
    settings: SettingsDep,
    limit: Annotated[
        int | None,
        Query(
            ge=1,
            le=MAX_HISTORY_POINTS,
            description="At most this many points, the newest (default BACKLASH_HISTORY_POINTS, 1000 unless set).",
        ),
    ] = None,
    before: Annotated[
        AwareDatetime | None,
        Query(
            description="Only points measured before this instant (ISO 8601 with a UTC offset): the previous "
            "answer's `next_before` reads the next, older points."
        ),
    ] = None,
) -> Any:
    """Identifications (continuous width K with its 1-sigma uncertainty) and diagnoses (verdict, and the width
    their calibration found), oldest measurement first. The trend uses the identifications (``used_in_trend``).

    One answer holds the newest ``limit`` points; ``more`` says whether older ones exist, and ``next_before``
    reads them."""
    page = asset_service.history(store, asset, limit or settings.history_points, before)
    return HistoryPublic(
        asset=asset,
        points=[HistoryPointPublic(**p) for p in page.points],
        more=page.more,
        next_before=page.next_before,
    )


@router.get(
    "/{asset}/trend",
    response_model=TrendPublic,
    summary="How fast an asset's width grows and when it passes a limit",
    responses={**_NOT_FOUND, 422: {"model": ErrorPublic, "description": "Too little history for a trend"}},
)
def read_trend(asset: AssetPath, limit: LimitQuery, store: StoreDep) -> Any:
    """A straight line through the identified widths over time, weighted by their uncertainties, its scatter
    taken into account; the crossing date of ``limit`` with an interval (``method`` says what it assumes;
    docs/trend.md)."""
    fitted = asset_service.trend(store, asset, limit)
    return TrendPublic(asset=asset, **fitted.to_dict())


@router.get(
    "/{asset}/trend/figure",
    response_class=Response,
    summary="An asset's width history with its trend and the limit (PNG)",
    responses={
        200: {
            "content": {"image/png": {"schema": {"type": "string", "format": "binary"}}},
            "description": "The figure",
        },
        404: {"model": ErrorPublic, "description": "No such asset, or no identified width of it to draw"},
    },
)
async def read_trend_figure(asset: AssetPath, store: StoreDep, limit: LimitQuery | None = None) -> Response:
    """The trend is drawn when ``limit`` is given and the history is long enough; the history always. An asset
    with no identified width (diagnoses only, or identifications without a continuous width) has nothing to
    draw: 404 saying so."""

    def draw() -> bytes:
        with tempfile.TemporaryDirectory(prefix="backlash-trend-") as tmp:
            return asset_service.trend_figure(store, asset, limit, Path(tmp) / "trend.png").read_bytes()

    png = await run_in_threadpool(draw)
    return Response(png, media_type="image/png", headers={"Cache-Control": "no-store"})
