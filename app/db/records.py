"""The ``records`` table: every record the service was asked to diagnose, as it was sent.

A record is kept as its request body (JSON, or the CSV text with the query parameters that
complete it), compressed, so that a diagnosis can be run again (a retried job) and a stored record
can be picked again in the report page, read by exactly the code that read it the first time.

The whole body is kept, however long the record (issue 54), though a diagnosis holds only the excerpt
around the event of a long CSV (:mod:`engine.records.streamed`): where the event lies, the noise level
the locator uses and whether the record is refused all depend on every sample, so only the whole body
reads again to the same answer, and nothing a user sent is lost. What that costs is bounded by the
request body's limit (``BACKLASH_MAX_BODY_BYTES``, 32 MiB by default) and the compression.
"""

from __future__ import annotations

import builtins
import json
import sqlite3
import uuid
import zlib
from dataclasses import dataclass
from datetime import datetime
from typing import Any, Literal

from app.db.codec import from_text, now, to_text
from engine.storage import PatternStore

__all__ = ["NewRecord", "RecordRepository", "StoredRecord"]

Media = Literal["json", "csv"]

_SUMMARY = "id, plant, name, asset, measured_at, n_samples, created_at, media, params"


@dataclass(frozen=True)
class StoredRecord:
    """A stored record's metadata; ``body`` (the bytes as sent) only when read with :meth:`RecordRepository.get`.

    Attributes
    ----------
    media : {"json", "csv"}
        How the body was sent.
    params : dict
        The query parameters that completed a CSV body (empty for JSON).
    """

    id: str
    plant: str
    name: str | None
    asset: str | None
    measured_at: datetime | None
    n_samples: int
    created_at: datetime
    media: Media
    params: dict[str, Any]
    body: bytes | None = None


@dataclass(frozen=True)
class NewRecord:
    """A record about to be stored (:meth:`RecordRepository.new`): its metadata and its compressed body."""

    record: StoredRecord
    body_z: bytes


def _row(row: tuple[Any, ...], body: bytes | None = None) -> StoredRecord:
    created = from_text(row[6])
    assert created is not None
    return StoredRecord(
        id=row[0],
        plant=row[1],
        name=row[2],
        asset=row[3],
        measured_at=from_text(row[4]),
        n_samples=int(row[5]),
        created_at=created,
        media=row[7],
        params=json.loads(row[8]),
        body=body,
    )


class RecordRepository:
    """Records in the store's SQLite file."""

    def __init__(self, store: PatternStore) -> None:
        self.store = store

    def add(self, new: NewRecord) -> StoredRecord:
        """Store a record made by :meth:`new` (in a transaction of its own); return its metadata."""
        with self.store.writing() as conn:
            self.insert(conn, new)
        return new.record

    @staticmethod
    def new(
        body: bytes,
        *,
        media: Media,
        params: dict[str, Any],
        plant: str,
        name: str | None,
        asset: str | None,
        measured_at: datetime | None,
        n_samples: int,
    ) -> NewRecord:
        """A record to store (a new id, the body compressed), not stored yet: :meth:`insert` stores it."""
        record = StoredRecord(
            id=uuid.uuid4().hex,
            plant=plant,
            name=name,
            asset=asset,
            measured_at=measured_at,
            n_samples=int(n_samples),
            created_at=now(),
            media=media,
            params=dict(params),
        )
        return NewRecord(record, zlib.compress(body, 6))

    @staticmethod
    def insert(conn: sqlite3.Connection, new: NewRecord) -> None:
        """Store ``new`` in the caller's write transaction ``conn`` (with the rows that belong with it)."""
        rec = new.record
        conn.execute(
            f"INSERT INTO records ({_SUMMARY}, body_z) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (
                rec.id,
                rec.plant,
                rec.name,
                rec.asset,
                to_text(rec.measured_at),
                rec.n_samples,
                to_text(rec.created_at),
                rec.media,
                json.dumps(rec.params, allow_nan=False),
                new.body_z,
            ),
        )

    def get(self, record_id: str) -> StoredRecord | None:
        """The record with its body, or ``None``."""
        with self.store.reading() as conn:
            row = conn.execute(f"SELECT {_SUMMARY}, body_z FROM records WHERE id = ?", (record_id,)).fetchone()
        return None if row is None else _row(row[:-1], zlib.decompress(row[-1]))

    def list(self, *, asset: str | None = None, limit: int = 100) -> builtins.list[StoredRecord]:
        """Records' metadata, newest first (of one asset if given)."""
        sql, args = f"SELECT {_SUMMARY} FROM records", []
        if asset is not None:
            sql += " WHERE asset = ?"
            args.append(asset)
        with self.store.reading() as conn:
            rows = conn.execute(sql + " ORDER BY seq DESC LIMIT ?", (*args, int(limit))).fetchall()
        return [_row(r) for r in rows]

    def delete(self, record_id: str) -> None:
        with self.store.writing() as conn:
            conn.execute("DELETE FROM records WHERE id = ?", (record_id,))
