"""The ``diagnoses`` and ``figures`` tables: each diagnosis job's result and its PNG figures.

A diagnosis row is written when the job is queued (no result yet) and completed by the job
(:meth:`DiagnosisRepository.complete`: the result, its verdict's summary columns and the
figures in one transaction, the one that also marks the job done), so that a diagnosis is either
whole or absent.
"""

from __future__ import annotations

import builtins
import contextlib
import sqlite3
import uuid
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from app.db.codec import from_text, now, pack, to_text, unpack
from engine.storage import PatternStore

__all__ = ["DiagnosisRepository", "StoredDiagnosis"]

_COLUMNS = "id, job_id, record_id, plant, asset, measured_at, created_at, status, effect, width, width_sigma"


@dataclass(frozen=True)
class StoredDiagnosis:
    """A stored diagnosis; ``result`` (the diagnosis answer) only when read with ``with_result``.

    Attributes
    ----------
    status, effect : str or None
        The verdict's status and named effect (``None`` until the job has finished).
    width, width_sigma : float or None
        The backlash width the diagnosis found [m] and its 1-sigma uncertainty, where it reports one.
    figures : list of str
        Names of the stored figures.
    """

    id: str
    job_id: str
    record_id: str
    plant: str
    asset: str | None
    measured_at: datetime | None
    created_at: datetime
    status: str | None
    effect: str | None
    width: float | None
    width_sigma: float | None
    result: dict[str, Any] | None = None
    figures: tuple[str, ...] = ()


class DiagnosisRepository:
    """Diagnoses and their figures in the store's SQLite file."""

    def __init__(self, store: PatternStore) -> None:
        self.store = store

    def create(
        self,
        *,
        job_id: str,
        record_id: str,
        plant: str,
        asset: str | None,
        measured_at: datetime | None,
        diagnosis_id: str | None = None,
        conn: sqlite3.Connection | None = None,
    ) -> str:
        """Insert a diagnosis without a result yet (with the id ``diagnosis_id`` when given, else a new one; in the
        write transaction ``conn`` when given); return its id."""
        diagnosis_id = diagnosis_id or uuid.uuid4().hex
        with self.store.writing() if conn is None else contextlib.nullcontext(conn) as conn:
            conn.execute(
                "INSERT INTO diagnoses (id, job_id, record_id, plant, asset, measured_at, created_at) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (diagnosis_id, job_id, record_id, plant, asset, to_text(measured_at), to_text(now())),
            )
        return diagnosis_id

    def set_job(self, diagnosis_id: str, job_id: str, conn: sqlite3.Connection | None = None) -> None:
        """The job that now computes the diagnosis (a retry; in the write transaction ``conn`` when given)."""
        with self.store.writing() if conn is None else contextlib.nullcontext(conn) as conn:
            conn.execute("UPDATE diagnoses SET job_id = ? WHERE id = ?", (job_id, diagnosis_id))

    @staticmethod
    def has_result(conn: sqlite3.Connection, diagnosis_id: str) -> bool:
        """Whether the diagnosis exists with its result stored (read in ``conn``, e.g. a retry's transaction)."""
        row = conn.execute("SELECT 1 FROM diagnoses WHERE id = ? AND result_z IS NOT NULL", (diagnosis_id,)).fetchone()
        return row is not None

    def complete(
        self,
        diagnosis_id: str,
        result: dict[str, Any],
        *,
        status: str | None,
        effect: str | None,
        width: float | None,
        width_sigma: float | None,
        figures: dict[str, bytes],
        conn: sqlite3.Connection | None = None,
    ) -> bool:
        """Store the result and figures in one transaction (``conn`` when given: the caller's, which also marks the
        job done, :func:`app.jobs.manager.finish_job`); False if the diagnosis was deleted meanwhile."""
        with self.store.writing() if conn is None else contextlib.nullcontext(conn) as conn:
            cur = conn.execute(
                "UPDATE diagnoses SET result_z = ?, status = ?, effect = ?, width = ?, width_sigma = ? WHERE id = ?",
                (pack(result), status, effect, width, width_sigma, diagnosis_id),
            )
            if cur.rowcount != 1:
                return False
            conn.execute("DELETE FROM figures WHERE owner_id = ?", (diagnosis_id,))
            conn.executemany(
                "INSERT INTO figures (owner_id, name, png) VALUES (?, ?, ?)",
                [(diagnosis_id, name, png) for name, png in figures.items()],
            )
        return True

    def get(self, diagnosis_id: str, *, with_result: bool = True) -> StoredDiagnosis | None:
        with self.store.reading() as conn:
            row = conn.execute(
                f"SELECT {_COLUMNS}{', result_z' if with_result else ''} FROM diagnoses WHERE id = ?", (diagnosis_id,)
            ).fetchone()
            if row is None:
                return None
            names = [
                r[0] for r in conn.execute("SELECT name FROM figures WHERE owner_id = ? ORDER BY name", (diagnosis_id,))
            ]
        return self._row(row[:11], unpack(row[11]) if with_result else None, tuple(names))

    def list(self, *, asset: str | None = None, limit: int = 100) -> builtins.list[StoredDiagnosis]:
        """Diagnoses without their results, newest first (of one asset if given)."""
        sql, args = f"SELECT {_COLUMNS} FROM diagnoses", []
        if asset is not None:
            sql += " WHERE asset = ?"
            args.append(asset)
        with self.store.reading() as conn:
            rows = conn.execute(sql + " ORDER BY seq DESC LIMIT ?", (*args, int(limit))).fetchall()
        return [self._row(r, None, ()) for r in rows]

    def newest(self, asset: str, *, limit: int, before: datetime | None = None) -> builtins.list[StoredDiagnosis]:
        """The asset's ``limit`` most recently measured diagnoses (when the record was taken, else when it was
        stored; before ``before`` if given), newest first, without their results."""
        when = "coalesce(measured_at, created_at)"
        sql = f"SELECT {_COLUMNS} FROM diagnoses WHERE asset = ?"
        args: builtins.list[str] = [asset]
        if before is not None:
            sql += f" AND {when} < ?"
            args.append(str(to_text(before)))
        with self.store.reading() as conn:
            rows = conn.execute(sql + f" ORDER BY {when} DESC, seq DESC LIMIT ?", (*args, int(limit))).fetchall()
        return [self._row(r, None, ()) for r in rows]

    def asset_spans(self) -> dict[str, tuple[int, datetime | None, datetime | None]]:
        """Per named asset: how many rows, the first and the last ``measured_at`` (one query)."""
        with self.store.reading() as conn:
            rows = conn.execute(
                "SELECT asset, count(*), min(measured_at), max(measured_at) FROM diagnoses "
                "WHERE asset IS NOT NULL GROUP BY asset"
            ).fetchall()
        return {r[0]: (int(r[1]), from_text(r[2]), from_text(r[3])) for r in rows}

    def figure(self, diagnosis_id: str, name: str) -> bytes | None:
        with self.store.reading() as conn:
            row = conn.execute(
                "SELECT png FROM figures WHERE owner_id = ? AND name = ?", (diagnosis_id, name)
            ).fetchone()
        return None if row is None else bytes(row[0])

    def delete(self, diagnosis_id: str) -> None:
        """Remove the diagnosis and its figures (one transaction)."""
        with self.store.writing() as conn:
            conn.execute("DELETE FROM figures WHERE owner_id = ?", (diagnosis_id,))
            conn.execute("DELETE FROM diagnoses WHERE id = ?", (diagnosis_id,))

    @staticmethod
    def _row(row: tuple[Any, ...], result: dict[str, Any] | None, figures: tuple[str, ...]) -> StoredDiagnosis:
        created = from_text(row[6])
        assert created is not None
        return StoredDiagnosis(
            id=row[0],
            job_id=row[1],
            record_id=row[2],
            plant=row[3],
            asset=row[4],
            measured_at=from_text(row[5]),
            created_at=created,
            status=row[7],
            effect=row[8],
            width=row[9],
            width_sigma=row[10],
            result=result,
            figures=figures,
        )
