"""The ``identifications`` table: identifications of named assets (a drive's width history)."""

from __future__ import annotations

import builtins
import uuid
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from app.db.codec import from_text, now, pack, to_text, unpack
from engine.storage import PatternStore

__all__ = ["IdentificationRepository", "StoredIdentification"]

_COLUMNS = "id, asset, measured_at, created_at, channel, width, width_sigma"


@dataclass(frozen=True)
class StoredIdentification:
    """One stored identification: the continuous width [m] with its 1-sigma uncertainty, and the whole answer."""

    id: str
    asset: str
    measured_at: datetime
    created_at: datetime
    channel: str | None
    width: float | None
    width_sigma: float | None
    result: dict[str, Any] | None = None


class IdentificationRepository:
    """Identifications of named assets in the store's SQLite file."""

    def __init__(self, store: PatternStore) -> None:
        self.store = store

    def add(
        self,
        *,
        asset: str,
        measured_at: datetime,
        channel: str | None,
        width: float | None,
        width_sigma: float | None,
        result: dict[str, Any],
    ) -> str:
        identification_id = uuid.uuid4().hex
        with self.store.writing() as conn:
            conn.execute(
                f"INSERT INTO identifications ({_COLUMNS}, result_z) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    identification_id,
                    asset,
                    to_text(measured_at),
                    to_text(now()),
                    channel,
                    width,
                    width_sigma,
                    pack(result),
                ),
            )
        return identification_id

    def list(self, *, asset: str | None = None, limit: int = 10_000) -> builtins.list[StoredIdentification]:
        """Identifications without their answers, oldest measurement first (of one asset if given)."""
        sql, args = f"SELECT {_COLUMNS} FROM identifications", []
        if asset is not None:
            sql += " WHERE asset = ?"
            args.append(asset)
        with self.store.reading() as conn:
            rows = conn.execute(sql + " ORDER BY measured_at, seq LIMIT ?", (*args, int(limit))).fetchall()
        return [self._row(r) for r in rows]

    def newest(self, asset: str, *, limit: int, before: datetime | None = None) -> builtins.list[StoredIdentification]:
        """The asset's ``limit`` most recently measured identifications (measured before ``before`` if given),
        newest first, without their answers (index ``identifications_asset``)."""
        sql = f"SELECT {_COLUMNS} FROM identifications WHERE asset = ?"
        args: builtins.list[str] = [asset]
        if before is not None:
            sql += " AND measured_at < ?"
            args.append(str(to_text(before)))
        with self.store.reading() as conn:
            rows = conn.execute(sql + " ORDER BY measured_at DESC, seq DESC LIMIT ?", (*args, int(limit))).fetchall()
        return [self._row(r) for r in rows]

    def asset_spans(self) -> dict[str, tuple[int, datetime | None, datetime | None]]:
        """Per named asset: how many rows, the first and the last ``measured_at`` (one query)."""
        with self.store.reading() as conn:
            rows = conn.execute(
                "SELECT asset, count(*), min(measured_at), max(measured_at) FROM identifications "
                "WHERE asset IS NOT NULL GROUP BY asset"
            ).fetchall()
        return {r[0]: (int(r[1]), from_text(r[2]), from_text(r[3])) for r in rows}

    def get(self, identification_id: str) -> StoredIdentification | None:
        with self.store.reading() as conn:
            row = conn.execute(
                f"SELECT {_COLUMNS}, result_z FROM identifications WHERE id = ?", (identification_id,)
            ).fetchone()
        return None if row is None else self._row(row[:7], unpack(row[7]))

    def delete(self, identification_id: str) -> bool:
        """Remove the identification (nothing else refers to one); False if there was none."""
        with self.store.writing() as conn:
            cur = conn.execute("DELETE FROM identifications WHERE id = ?", (identification_id,))
            return cur.rowcount == 1

    @staticmethod
    def _row(row: tuple[Any, ...], result: dict[str, Any] | None = None) -> StoredIdentification:
        measured, created = from_text(row[2]), from_text(row[3])
        assert measured is not None and created is not None
        return StoredIdentification(
            id=row[0],
            asset=row[1],
            measured_at=measured,
            created_at=created,
            channel=row[4],
            width=row[5],
            width_sigma=row[6],
            result=result,
        )
