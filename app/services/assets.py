"""Drives ("assets"): their identifications are stored, their width history read back and its trend fitted.

The trend uses the identifications of an asset (each a continuous width with its 1-sigma
uncertainty, one per identified record): one estimator, each record once. Diagnoses appear in
the history with the width their calibration found and their verdict, but are not fitted: a
diagnosis of the same record as an identification would count that record twice, and a
record with an unexplained gap biases its calibrated width. The method itself is
:func:`engine.history.trend.fit_trend` (docs/trend.md).
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path
from typing import Any

from app.db.codec import now
from app.db.diagnoses import DiagnosisRepository
from app.db.identifications import IdentificationRepository
from app.services.errors import InvalidInputError, NotFoundError
from engine.history.trend import Trend, TrendError, WidthPoint, fit_trend
from engine.storage import PatternStore

__all__ = ["assets", "history", "store_identification", "trend", "trend_figure"]


def store_identification(
    store: PatternStore, asset: str, measured_at: datetime | None, channel: str | None, answer: dict[str, Any]
) -> tuple[str, datetime]:
    """Store an identification of ``asset`` (its continuous width, if the answer has one); return (id, measured_at)."""
    continuous = answer.get("continuous") or {}
    when = measured_at or now()
    identification_id = IdentificationRepository(store).add(
        asset=asset,
        measured_at=when,
        channel=channel,
        width=continuous.get("K"),
        width_sigma=continuous.get("sigma_K"),
        result=answer,
    )
    return identification_id, when


def assets(store: PatternStore) -> list[dict[str, Any]]:
    """Every asset with its counts and the span of its measurements, by name (two grouped queries)."""
    idents = IdentificationRepository(store).asset_spans()
    diags = DiagnosisRepository(store).asset_spans()
    out = []
    for name in sorted(idents.keys() | diags.keys()):
        n_i, first_i, last_i = idents.get(name, (0, None, None))
        n_d, first_d, last_d = diags.get(name, (0, None, None))
        firsts = [t for t in (first_i, first_d) if t is not None]
        lasts = [t for t in (last_i, last_d) if t is not None]
        out.append(
            {
                "asset": name,
                "n_identifications": n_i,
                "n_diagnoses": n_d,
                "first_measured_at": min(firsts, default=None),
                "last_measured_at": max(lasts, default=None),
            }
        )
    return out


def history(store: PatternStore, asset: str) -> list[dict[str, Any]]:
    """The asset's identifications and diagnoses, oldest measurement first; 404 for an unknown asset."""
    points: list[dict[str, Any]] = [
        {
            "measured_at": i.measured_at,
            "kind": "identification",
            "id": i.id,
            "K": i.width,
            "K_sigma": i.width_sigma,
            "status": None,
            "effect": None,
            "used_in_trend": i.width is not None,
        }
        for i in IdentificationRepository(store).list(asset=asset)
    ]
    points += [
        {
            "measured_at": d.measured_at or d.created_at,
            "kind": "diagnosis",
            "id": d.id,
            "K": d.width,
            "K_sigma": d.width_sigma,
            "status": d.status,
            "effect": d.effect,
            "used_in_trend": False,
        }
        for d in DiagnosisRepository(store).list(asset=asset, limit=1_000_000)
    ]
    if not points:
        raise NotFoundError(f"no identification or diagnosis of asset {asset!r} is stored; GET /v1/assets lists them")
    return sorted(points, key=lambda p: p["measured_at"])


def _width_points(store: PatternStore, asset: str) -> list[WidthPoint]:
    pts = [p for p in history(store, asset) if p["used_in_trend"]]
    return [WidthPoint(p["measured_at"], float(p["K"]), p["K_sigma"]) for p in pts]


def trend(store: PatternStore, asset: str, limit: float) -> Trend:
    """The width's growth and when it passes ``limit`` [m]; ``InvalidInputError`` (422) when the history is too short."""
    points = _width_points(store, asset)
    try:
        return fit_trend(points, limit)
    except TrendError as exc:
        raise InvalidInputError(f"asset {asset!r}: {exc}") from None


def trend_figure(store: PatternStore, asset: str, limit: float | None, out: Path) -> Path:
    """The history, the fitted trend (when there is enough history) and the limit, as PNG at ``out``."""
    from engine.history.plots import plot_history

    points = _width_points(store, asset)  # NotFoundError (404) for an unknown asset
    if not points:
        raise NotFoundError(
            f"asset {asset!r} has no identified width to draw (its history holds only diagnoses, or "
            "identifications without a continuous width); identify one of its records with POST /v1/identify "
            "(the record naming the asset), then the figure shows it"
        )
    fitted: Trend | None = None
    if limit is not None:
        try:
            fitted = fit_trend(points, limit)
        except TrendError:
            fitted = None  # the figure still shows the history
    return plot_history(points, fitted, limit, out, title=f"Backlash width of {asset}")
