"""Drives ("assets"): their identifications are stored, their width history read back and its trend fitted.

The trend uses the identifications of an asset (each a continuous width with its 1-sigma
uncertainty, one per identified record): one estimator, each record once. Diagnoses appear in
the history with the width their calibration found and their verdict, but are not fitted: a
diagnosis of the same record as an identification would count that record twice, and a
record with an unexplained gap biases its calibrated width. The method itself is
:func:`engine.history.trend.fit_trend` (docs/trend.md).

An asset is one machine: its measurements are of one drive description (issue 52), or of one other plant
(EMPS, the BRFD, an uploaded plant: :func:`machine_key`). A measurement of another machine than the asset's
newest one is refused before it is stored (:func:`check_asset_drive`), so that a history and its trend
never mix the measurements of two machines.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from app.core.config import MAX_HISTORY_POINTS
from app.db.codec import now
from app.db.diagnoses import DiagnosisRepository
from app.db.identifications import IdentificationRepository
from app.services.errors import IncompatibleError, InvalidInputError, NotFoundError
from engine.history.trend import Trend, TrendError, WidthPoint, fit_trend
from engine.plants import DEFAULT_PLANT
from engine.simulation.drive import REFERENCE_DRIVE
from engine.storage import PatternStore

#: Prefix of the machine key of a plant other than the backlash drive (then its registry name or uploaded id).
PLANT_KEY = "plant:"

#: Newest diagnoses of an asset looked through for one whose drive is known (the newest one's record may be gone).
MAX_PENDING_LOOKUP = 20

__all__ = [
    "HistoryPage",
    "asset_drive",
    "assets",
    "check_asset_drive",
    "history",
    "store_identification",
    "trend",
    "trend_figure",
]


def machine_key(plant: str, drive: str | None = None) -> str:
    """What an asset's measurements must all be of: a backlash drive (its description's fingerprint ``drive``;
    MODEL.md's reference drive when None), or another plant, by its name or uploaded id (``plant:<plant>``)."""
    if plant != DEFAULT_PLANT:
        return PLANT_KEY + plant
    return REFERENCE_DRIVE.fingerprint if drive is None else drive


def _machine(key: str) -> str:
    """A machine key as a message names it."""
    return f"plant {key.removeprefix(PLANT_KEY)}" if key.startswith(PLANT_KEY) else f"drive {key[:12]}"


def measurement_drive(answer: dict[str, Any] | None) -> str:
    """The fingerprint of the drive a stored answer was made on: an identification's ``drive`` (a fingerprint), a
    diagnosis's ``drive`` (its provenance); MODEL.md's reference plant when the answer names none."""
    stated = (answer or {}).get("drive")
    if isinstance(stated, str):
        return stated
    if isinstance(stated, dict) and isinstance(stated.get("fingerprint"), str):
        return str(stated["fingerprint"])
    return REFERENCE_DRIVE.fingerprint


def submitted_drive(store: PatternStore, record_id: str) -> str | None:
    """The fingerprint of the drive a stored diagnosis record was submitted with (its request read again, as its job
    reads it), or None when the record is gone or no longer reads."""
    from app.db.records import RecordRepository
    from app.services.diagnosis_requests import DiagnosisRequest, parse

    stored = RecordRepository(store).get(record_id)
    if stored is None:
        return None
    try:
        parsed = parse(DiagnosisRequest(stored.media, stored.body or b"", stored.params, store=str(store.path)))
    except (InvalidInputError, IncompatibleError):
        return None
    return machine_key(parsed.plant, None if parsed.drive is None else parsed.drive.fingerprint)


def asset_drive(store: PatternStore, asset: str) -> str | None:
    """The machine (:func:`machine_key`) of ``asset``'s newest measurement (None: it has none yet).

    A diagnosis counts from its submission: one still queued or running (or one that ended without an answer) is of
    the drive its stored request names (:func:`submitted_drive`), so two measurements of different drives submitted
    one after the other cannot both enter the asset's history.
    """
    newest: list[tuple[datetime, str]] = []
    for i in IdentificationRepository(store).newest(asset, limit=1):
        found = IdentificationRepository(store).get(i.id)
        if found is not None and found.result is not None:
            newest.append((i.measured_at, measurement_drive(found.result)))
    for d in DiagnosisRepository(store).newest(asset, limit=MAX_PENDING_LOOKUP):
        stored = DiagnosisRepository(store).get(d.id)
        if stored is None:
            continue
        if stored.plant != DEFAULT_PLANT:
            drive: str | None = machine_key(stored.plant)
        else:
            drive = (
                measurement_drive(stored.result) if stored.result is not None else submitted_drive(store, d.record_id)
            )
        if drive is not None:
            newest.append((d.measured_at or d.created_at, drive))
            break
    if not newest:
        return None
    return max(newest, key=lambda p: p[0])[1]


def check_asset_drive(store: PatternStore, asset: str | None, machine: str) -> None:
    """Refuse a measurement of ``asset`` made on another machine (:func:`machine_key`) than the asset's newest one.

    Raises
    ------
    IncompatibleError
        The asset's newest measurement is of another machine (422): the message names both and what to do.
    """
    if asset is None:
        return
    known = asset_drive(store, asset)
    if known is not None and known != machine:
        raise IncompatibleError(
            f"asset {asset!r} holds measurements of {_machine(known)}, and this one is of {_machine(machine)}: an "
            "asset's history is one machine's; give the asset's own drive description or plant, or another asset name"
        )


def store_identification(
    store: PatternStore, asset: str, measured_at: datetime | None, channel: str | None, answer: dict[str, Any]
) -> tuple[str, datetime]:
    """Store an identification of ``asset`` (its continuous width, if the answer has one); return (id, measured_at).

    Raises ``IncompatibleError`` when the asset's measurements are of another drive (:func:`check_asset_drive`).
    """
    check_asset_drive(store, asset, measurement_drive(answer))
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


@dataclass(frozen=True)
class HistoryPage:
    """One page of an asset's history.

    Attributes
    ----------
    points : list of dict
        Oldest measurement first: the newest ``limit`` points measured before the page's ``before``.
    more : bool
        Whether older points exist than the page holds.
    next_before : datetime or None
        When ``more``: the ``before`` that reads the next (older) page, the oldest measurement of this one.
    """

    points: list[dict[str, Any]]
    more: bool
    next_before: datetime | None


def history(store: PatternStore, asset: str, limit: int, before: datetime | None = None) -> HistoryPage:
    """The asset's newest ``limit`` identifications and diagnoses (measured before ``before`` if given), oldest
    measurement first; 404 for an unknown asset.

    Each table is read newest first with ``limit + 1`` rows at most (indexed by asset and measurement time), so an
    answer costs what it holds, however long the history. A page never ends inside a group of points measured at
    the same instant when older ones follow: that group moves to the next page (unless it alone fills the page),
    so that ``before`` = ``next_before`` reads every point once.
    """
    n = int(limit)
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
        for i in IdentificationRepository(store).newest(asset, limit=n + 1, before=before)
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
        for d in DiagnosisRepository(store).newest(asset, limit=n + 1, before=before)
    ]
    if not points:
        if before is not None and _known(store, asset):
            return HistoryPage([], False, None)
        raise NotFoundError(f"no identification or diagnosis of asset {asset!r} is stored; GET /v1/assets lists them")
    points.sort(key=lambda p: p["measured_at"], reverse=True)  # newest first
    page, left = points[:n], points[n:]
    if left and page[-1]["measured_at"] == left[0]["measured_at"]:
        cut = [p for p in page if p["measured_at"] != left[0]["measured_at"]]
        page = cut or page  # a group larger than the page stays whole on it
    more = bool(left)
    return HistoryPage(page[::-1], more, page[-1]["measured_at"] if more else None)


def _known(store: PatternStore, asset: str) -> bool:
    """Whether anything of ``asset`` is stored."""
    return bool(
        IdentificationRepository(store).newest(asset, limit=1) or DiagnosisRepository(store).newest(asset, limit=1)
    )


def _width_points(store: PatternStore, asset: str) -> list[WidthPoint]:
    """The identified widths the trend fits: the newest :data:`~app.core.config.MAX_HISTORY_POINTS`
    identifications of the asset with a width, oldest first; 404 for an unknown asset."""
    found = IdentificationRepository(store).newest(asset, limit=MAX_HISTORY_POINTS)
    if not found and not _known(store, asset):
        raise NotFoundError(f"no identification or diagnosis of asset {asset!r} is stored; GET /v1/assets lists them")
    return [WidthPoint(i.measured_at, float(i.width), i.width_sigma) for i in reversed(found) if i.width is not None]


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
