"""The ``fmus`` and ``plants`` tables: the users' own simulators, as FMU archives, and the plants that use them.

An FMU archive is stored once, under the SHA-256 of its bytes; a plant is a description (JSON, its
``fmu`` naming an archive by hash) under an id derived from the description and the archive, so the
same description of the same FMU is the same plant however often it is sent.
"""

from __future__ import annotations

import builtins
import json
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from app.db.codec import from_text, now, to_text
from engine.storage import PatternStore

__all__ = ["PlantRepository", "StoredFmu", "StoredPlant"]


@dataclass(frozen=True)
class StoredFmu:
    """A stored FMU archive's metadata (``summary``: :class:`engine.plants.fmu.archive.FmuSummary` as a dict)."""

    sha256: str
    size: int
    summary: dict[str, Any]
    created_at: datetime


@dataclass(frozen=True)
class StoredPlant:
    """A stored plant: its id, name, FMU and description (a :class:`~engine.plants.fmu.PlantDescription` dict)."""

    id: str
    name: str
    fmu_sha256: str
    description: dict[str, Any]
    created_at: datetime


def _datetime(text: str) -> datetime:
    moment = from_text(text)
    assert moment is not None
    return moment


class PlantRepository:
    """FMU archives and plants in the store's SQLite file."""

    def __init__(self, store: PatternStore) -> None:
        self.store = store

    def add_fmu(self, sha256: str, summary: dict[str, Any], content: bytes) -> tuple[StoredFmu, bool]:
        """Store an archive under its hash (nothing is written when it is stored already); it and whether it is new."""
        with self.store.writing() as conn:
            row = conn.execute("SELECT size, summary, created_at FROM fmus WHERE sha256 = ?", (sha256,)).fetchone()
            if row is not None:
                return StoredFmu(sha256, int(row[0]), json.loads(row[1]), _datetime(row[2])), False
            created = now()
            conn.execute(
                "INSERT INTO fmus (sha256, size, summary, created_at, content) VALUES (?, ?, ?, ?, ?)",
                (sha256, len(content), json.dumps(summary, allow_nan=False), to_text(created), content),
            )
        return StoredFmu(sha256, len(content), summary, created), True

    def get_fmu(self, sha256: str) -> StoredFmu | None:
        """An archive's metadata, or ``None``."""
        with self.store.reading() as conn:
            row = conn.execute("SELECT size, summary, created_at FROM fmus WHERE sha256 = ?", (sha256,)).fetchone()
        return None if row is None else StoredFmu(sha256, int(row[0]), json.loads(row[1]), _datetime(row[2]))

    def fmu_content(self, sha256: str) -> bytes | None:
        """An archive's bytes, or ``None``."""
        with self.store.reading() as conn:
            row = conn.execute("SELECT content FROM fmus WHERE sha256 = ?", (sha256,)).fetchone()
        return None if row is None else bytes(row[0])

    def add_plant(
        self, plant_id: str, name: str, fmu_sha256: str, description: dict[str, Any]
    ) -> tuple[StoredPlant, bool]:
        """Store a plant (nothing is written when ``plant_id`` is stored already); it and whether it is new."""
        with self.store.writing() as conn:
            old = conn.execute(
                "SELECT id, name, fmu_sha256, description, created_at FROM plants WHERE id = ?", (plant_id,)
            ).fetchone()
            if old is not None:
                return _plant(old), False
            if conn.execute("SELECT 1 FROM fmus WHERE sha256 = ?", (fmu_sha256,)).fetchone() is None:
                raise LookupError(fmu_sha256)  # checked by the caller; here only for a concurrent deletion
            created = now()
            text = json.dumps(description, allow_nan=False, sort_keys=True)
            conn.execute(
                "INSERT INTO plants (id, name, fmu_sha256, description, created_at) VALUES (?, ?, ?, ?, ?)",
                (plant_id, name, fmu_sha256, text, to_text(created)),
            )
        return StoredPlant(plant_id, name, fmu_sha256, description, created), True

    def get_plant(self, plant_id: str) -> StoredPlant | None:
        """A plant, or ``None``."""
        with self.store.reading() as conn:
            row = conn.execute(
                "SELECT id, name, fmu_sha256, description, created_at FROM plants WHERE id = ?", (plant_id,)
            ).fetchone()
        return None if row is None else _plant(row)

    def list_plants(self, limit: int = 100) -> builtins.list[StoredPlant]:
        """Plants, newest first."""
        with self.store.reading() as conn:
            rows = conn.execute(
                "SELECT id, name, fmu_sha256, description, created_at FROM plants ORDER BY seq DESC LIMIT ?",
                (int(limit),),
            ).fetchall()
        return [_plant(r) for r in rows]

    def delete_plant(self, plant_id: str) -> int:
        """Delete a plant unless a stored record names it, and its FMU when no other plant uses it.

        Returns the number of stored records that name it (the plant is kept when there are any).
        """
        with self.store.writing() as conn:
            used = int(conn.execute("SELECT count(*) FROM records WHERE plant = ?", (plant_id,)).fetchone()[0])
            if used:
                return used
            row = conn.execute("SELECT fmu_sha256 FROM plants WHERE id = ?", (plant_id,)).fetchone()
            if row is None:
                return 0
            conn.execute("DELETE FROM plants WHERE id = ?", (plant_id,))
            if conn.execute("SELECT 1 FROM plants WHERE fmu_sha256 = ?", (row[0],)).fetchone() is None:
                conn.execute("DELETE FROM fmus WHERE sha256 = ?", (row[0],))
        return 0


def _plant(row: tuple[Any, ...]) -> StoredPlant:
    return StoredPlant(row[0], row[1], row[2], json.loads(row[3]), _datetime(row[4]))
