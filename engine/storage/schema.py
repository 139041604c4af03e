"""The pattern store's SQLite schema, its version and the migrations that reach it.

The file carries ``PRAGMA application_id`` :data:`APPLICATION_ID` and ``PRAGMA user_version``
:data:`SCHEMA_VERSION`; :func:`migrate` upgrades an older file (or initialises an empty one)
when a store is opened.
"""

from __future__ import annotations

import logging
import sqlite3
from collections.abc import Callable
from pathlib import Path

from engine.storage.errors import PatternStoreError

logger = logging.getLogger(__name__)

__all__ = ["APPLICATION_ID", "FULL_COLUMNS", "MIGRATIONS", "SCHEMA_VERSION", "SUMMARY_COLUMNS", "migrate"]

#: ``PRAGMA application_id`` marking a file as a backlash pattern store ("BKLS").
APPLICATION_ID = 0x424B4C53


def _migrate_0_to_1(conn: sqlite3.Connection) -> None:
    """Create the initial schema."""
    conn.execute(
        """
        CREATE TABLE pattern_sets (
            seq            INTEGER PRIMARY KEY AUTOINCREMENT,
            id             TEXT NOT NULL UNIQUE,
            kind           TEXT NOT NULL,
            channel        TEXT NOT NULL,
            c              REAL NOT NULL,
            j1_values      TEXT NOT NULL,
            wavelet        TEXT NOT NULL,
            params         TEXT NOT NULL,
            model_version  TEXT NOT NULL,
            created_at     TEXT NOT NULL,
            arrays_meta    TEXT NOT NULL,
            arrays_sha256  TEXT NOT NULL,
            arrays_blob    BLOB NOT NULL
        )
        """
    )
    conn.execute("CREATE INDEX pattern_sets_lookup ON pattern_sets (channel, model_version, kind, c)")


def _migrate_1_to_2(conn: sqlite3.Connection) -> None:
    """Add the service's tables: jobs, the records it received, diagnoses (with their figures) and identifications.

    The pattern sets' table is unchanged. Timestamps are ISO 8601 text in UTC; JSON documents
    are zlib-compressed UTF-8 (``*_z`` columns); ``asset`` and ``measured_at`` index a drive's history.
    """
    conn.execute(
        """
        CREATE TABLE jobs (
            seq            INTEGER PRIMARY KEY AUTOINCREMENT,
            id             TEXT NOT NULL UNIQUE,
            kind           TEXT NOT NULL,
            state          TEXT NOT NULL,
            progress       REAL NOT NULL,
            stage          TEXT,
            error          TEXT,
            created_at     TEXT NOT NULL,
            started_at     TEXT,
            finished_at    TEXT,
            meta           TEXT NOT NULL,
            spec           TEXT NOT NULL,
            retry_of       TEXT
        )
        """
    )
    conn.execute("CREATE INDEX jobs_state ON jobs (state)")
    conn.execute(
        """
        CREATE TABLE records (
            seq            INTEGER PRIMARY KEY AUTOINCREMENT,
            id             TEXT NOT NULL UNIQUE,
            plant          TEXT NOT NULL,
            name           TEXT,
            asset          TEXT,
            measured_at    TEXT,
            n_samples      INTEGER NOT NULL,
            created_at     TEXT NOT NULL,
            media          TEXT NOT NULL,
            params         TEXT NOT NULL,
            body_z         BLOB NOT NULL
        )
        """
    )
    conn.execute("CREATE INDEX records_asset ON records (asset, measured_at)")
    conn.execute(
        """
        CREATE TABLE diagnoses (
            seq            INTEGER PRIMARY KEY AUTOINCREMENT,
            id             TEXT NOT NULL UNIQUE,
            job_id         TEXT NOT NULL,
            record_id      TEXT NOT NULL,
            plant          TEXT NOT NULL,
            asset          TEXT,
            measured_at    TEXT,
            created_at     TEXT NOT NULL,
            status         TEXT,
            effect         TEXT,
            width          REAL,
            width_sigma    REAL,
            result_z       BLOB
        )
        """
    )
    conn.execute("CREATE INDEX diagnoses_asset ON diagnoses (asset, measured_at)")
    conn.execute(
        """
        CREATE TABLE figures (
            owner_id       TEXT NOT NULL,
            name           TEXT NOT NULL,
            png            BLOB NOT NULL,
            PRIMARY KEY (owner_id, name)
        )
        """
    )
    conn.execute(
        """
        CREATE TABLE identifications (
            seq            INTEGER PRIMARY KEY AUTOINCREMENT,
            id             TEXT NOT NULL UNIQUE,
            asset          TEXT NOT NULL,
            measured_at    TEXT NOT NULL,
            created_at     TEXT NOT NULL,
            channel        TEXT,
            width          REAL,
            width_sigma    REAL,
            result_z       BLOB NOT NULL
        )
        """
    )
    conn.execute("CREATE INDEX identifications_asset ON identifications (asset, measured_at)")


def _migrate_2_to_3(conn: sqlite3.Connection) -> None:
    """Add the users' own plants: FMU archives by their SHA-256, and the plant descriptions that use them.

    An FMU is stored once however many descriptions use it (``fmus``, its archive's bytes and
    what it is as JSON); a plant (``plants``) is a description, as JSON with its ``fmu`` naming an
    archive of ``fmus`` by hash, under an id derived from both. Neither table is pruned by the
    retention: the records and diagnoses that name a plant need it to be read again.
    """
    conn.execute(
        """
        CREATE TABLE fmus (
            sha256         TEXT PRIMARY KEY,
            size           INTEGER NOT NULL,
            summary        TEXT NOT NULL,
            created_at     TEXT NOT NULL,
            content        BLOB NOT NULL
        )
        """
    )
    conn.execute(
        """
        CREATE TABLE plants (
            seq            INTEGER PRIMARY KEY AUTOINCREMENT,
            id             TEXT NOT NULL UNIQUE,
            name           TEXT NOT NULL,
            fmu_sha256     TEXT NOT NULL REFERENCES fmus (sha256),
            description    TEXT NOT NULL,
            created_at     TEXT NOT NULL
        )
        """
    )


#: Migration hook: ``MIGRATIONS[v]`` upgrades a database from schema version ``v`` to
#: ``v + 1`` inside the opening transaction. Append a function to change the schema;
#: :data:`SCHEMA_VERSION` follows.
MIGRATIONS: list[Callable[[sqlite3.Connection], None]] = [_migrate_0_to_1, _migrate_1_to_2, _migrate_2_to_3]
#: Schema version written by this code (``PRAGMA user_version``).
SCHEMA_VERSION = len(MIGRATIONS)

#: Columns of a summary row (metadata, array metadata, blob size), in this order.
SUMMARY_COLUMNS = (
    "id, kind, channel, c, j1_values, wavelet, params, model_version, created_at, arrays_meta, length(arrays_blob)"
)
#: Columns of a full row (metadata, checksum, blob), in this order.
FULL_COLUMNS = "id, kind, channel, c, j1_values, wavelet, params, model_version, created_at, arrays_sha256, arrays_blob"


def migrate(conn: sqlite3.Connection, path: Path) -> None:
    """Check the application id and run the pending :data:`MIGRATIONS`, inside the caller's transaction.

    Parameters
    ----------
    conn : sqlite3.Connection
        A connection in an open write transaction (``BEGIN IMMEDIATE``).
    path : Path
        The database file, for messages.

    Raises
    ------
    PatternStoreError
        The file belongs to another application, is a SQLite database but not a pattern
        store, or has a newer schema version than this code supports.
    """
    app_id = conn.execute("PRAGMA application_id").fetchone()[0]
    version = conn.execute("PRAGMA user_version").fetchone()[0]
    if app_id not in (0, APPLICATION_ID):
        raise PatternStoreError(f"{path} is a SQLite database of another application (application_id {app_id})")
    if app_id == 0:
        tables = conn.execute("SELECT count(*) FROM sqlite_master").fetchone()[0]
        if version != 0 or tables:
            raise PatternStoreError(f"{path} is a SQLite database but not a pattern store; choose another path")
    target = len(MIGRATIONS)
    if version > target:
        raise PatternStoreError(
            f"{path} has schema version {version}, newer than this code supports ({target}); upgrade backlash"
        )
    for v in range(version, target):
        logger.info("migrating pattern store %s from schema %d to %d", path, v, v + 1)
        MIGRATIONS[v](conn)
        conn.execute(f"PRAGMA user_version = {v + 1}")
    if app_id == 0:
        conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
