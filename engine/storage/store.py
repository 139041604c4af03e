"""Durable store for trained identifiers ("pattern sets", :mod:`engine.storage.models`).

:class:`PatternStore` keeps pattern sets in one embedded SQLite file (stdlib
:mod:`sqlite3`). Durability and concurrency come from SQLite itself:

* the database runs in WAL journal mode with ``synchronous=FULL``, so a
  committed save survives a crash or power loss, and readers never block
  writers;
* every save and delete is a single ``BEGIN IMMEDIATE`` transaction, so a
  process killed mid-write leaves the previous state intact;
* a connection is opened per operation (no connection is shared between
  threads or inherited across ``fork``) with a busy timeout, so concurrent
  writers from threads and processes queue for the write lock instead of
  failing;
* the array blob (:mod:`engine.storage.codec`) is an in-memory ``.npz`` written with ``allow_pickle=False``
  (bit-exact, dtype and shape preserved, never pickle) stored next to its
  SHA-256, which is checked on every read;
* the schema carries a version (``PRAGMA user_version``) and an application id;
  :data:`~engine.storage.schema.MIGRATIONS` upgrade older files when a store is opened;
* deleting rows frees pages inside the file but does not shrink it; :meth:`PatternStore.compact`
  gives them back to the file system. A new file is created with ``PRAGMA auto_vacuum =
  INCREMENTAL``, so compacting it is an ``incremental_vacuum`` (cheap: it moves only the pages
  it frees). A file created before that has ``auto_vacuum = NONE``, which SQLite can only change
  by rewriting the whole file: its first compaction that has free pages to give back runs
  ``VACUUM`` once (it then holds the write lock for the rewrite and needs free disk space of the
  file's size) and leaves the file incremental, so later compactions are cheap too. Either way a
  ``wal_checkpoint(TRUNCATE)`` follows, so that the database file and its ``-wal`` file shrink.

WAL needs shared memory between the processes using the file, so the database
must live on a local file system (not NFS/SMB).

Choosing a set for a record (the nearest c) is a policy, not storage: see
:func:`engine.identification.selection.nearest_pattern_set`.
"""

from __future__ import annotations

import builtins
import contextlib
import json
import logging
import os
import sqlite3
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from engine.storage.codec import decode_arrays, sha256
from engine.storage.errors import CorruptPatternSet, PatternSetExists, PatternSetNotFound, PatternStoreError
from engine.storage.models import PatternSet, PatternSetSummary
from engine.storage.paths import default_store_path
from engine.storage.schema import FULL_COLUMNS, SUMMARY_COLUMNS, migrate
from engine.storage.validation import prepare, require_c, require_channel

logger = logging.getLogger(__name__)

__all__ = ["Compaction", "PatternStore"]

#: ``PRAGMA auto_vacuum`` value of incremental vacuuming (0 none, 1 full, 2 incremental).
AUTO_VACUUM_INCREMENTAL = 2


@dataclass(frozen=True)
class Compaction:
    """What :meth:`PatternStore.compact` did.

    Attributes
    ----------
    method : {"incremental_vacuum", "vacuum", "none"}
        ``incremental_vacuum`` (an incremental file), ``vacuum`` (the one rewrite of a file created with
        ``auto_vacuum = NONE``, which also makes it incremental) or ``none`` (no free page to give back).
    bytes_before, bytes_after : int
        Size of the database file plus its ``-wal`` file before and after [bytes].
    free_pages_before : int
        Pages that were free inside the file (``PRAGMA freelist_count``) before.
    page_size : int
        SQLite's page size [bytes].
    checkpointed : bool
        Whether the closing ``wal_checkpoint(TRUNCATE)`` completed; if a reader held it back, the file shrinks
        at a later checkpoint.
    """

    method: str
    bytes_before: int
    bytes_after: int
    free_pages_before: int
    page_size: int
    checkpointed: bool

    @property
    def bytes_freed(self) -> int:
        """``bytes_before - bytes_after`` [bytes] (negative if the file grew meanwhile)."""
        return self.bytes_before - self.bytes_after


def _utc_now() -> str:
    return datetime.now(UTC).isoformat(timespec="microseconds")


def _is_locked(exc: sqlite3.Error) -> bool:
    msg = str(exc).lower()
    return "locked" in msg or "busy" in msg


class PatternStore:
    """Pattern sets in one SQLite file; safe to share between threads and processes.

    Parameters
    ----------
    path : str or os.PathLike or None
        Database file; created (with its parent directories) if missing.
        ``None`` uses :func:`default_store_path`.
    busy_timeout : float
        Seconds an operation waits for another writer's lock before raising
        :class:`PatternStoreError`.

    Raises
    ------
    PatternStoreError
        If the file is not a SQLite database, belongs to another application,
        or has a newer schema version than this code understands.

    Notes
    -----
    The object holds no open connection; each call opens, uses and closes one.
    It can therefore be shared freely between threads, and used after ``fork``.
    """

    def __init__(self, path: str | os.PathLike[str] | None = None, *, busy_timeout: float = 30.0) -> None:
        raw = default_store_path() if path is None else path
        if str(raw) in ("", ":memory:") or str(raw).startswith("file:"):
            raise ValueError(f"path must be a database file path, got {str(raw)!r} (use a temporary file for tests)")
        if not (busy_timeout > 0):
            raise ValueError(f"busy_timeout must be > 0 seconds, got {busy_timeout!r}")
        self.path = Path(raw).expanduser().resolve()
        self.busy_timeout = float(busy_timeout)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._initialise()

    def __repr__(self) -> str:
        return f"PatternStore({str(self.path)!r})"

    # -- connections -------------------------------------------------------------
    @contextlib.contextmanager
    def _connect(self) -> Iterator[sqlite3.Connection]:
        """Open a connection configured for durability; close it afterwards."""
        try:
            conn = sqlite3.connect(self.path, timeout=self.busy_timeout, isolation_level=None)
        except sqlite3.Error as exc:
            raise PatternStoreError(f"cannot open pattern store {self.path}: {exc}") from exc
        try:
            conn.execute(f"PRAGMA busy_timeout = {int(self.busy_timeout * 1000)}")
            conn.execute("PRAGMA synchronous = FULL")
            yield conn
        except sqlite3.IntegrityError:
            raise  # constraint violations are the caller's to interpret
        except sqlite3.OperationalError as exc:
            if _is_locked(exc):
                raise PatternStoreError(
                    f"pattern store {self.path} stayed locked by another writer for more than "
                    f"{self.busy_timeout:g} s: {exc}"
                ) from exc
            raise PatternStoreError(f"pattern store {self.path}: {exc}") from exc
        except sqlite3.DatabaseError as exc:
            raise PatternStoreError(f"pattern store {self.path} is unreadable: {exc}") from exc
        finally:
            conn.close()

    @contextlib.contextmanager
    def _write(self) -> Iterator[sqlite3.Connection]:
        """One write transaction: ``BEGIN IMMEDIATE`` ... ``COMMIT`` (``ROLLBACK`` on error)."""
        with self._connect() as conn:
            conn.execute("BEGIN IMMEDIATE")
            try:
                yield conn
            except BaseException:
                with contextlib.suppress(sqlite3.Error):
                    conn.execute("ROLLBACK")
                raise
            conn.execute("COMMIT")

    def reading(self) -> contextlib.AbstractContextManager[sqlite3.Connection]:
        """A connection for reads (closed on exit); errors become :class:`PatternStoreError`.

        For the other tables of the same file (the service's jobs, records, diagnoses, ...):
        one file, one schema (:mod:`engine.storage.schema`), one way to open it.
        """
        return self._connect()

    def writing(self) -> contextlib.AbstractContextManager[sqlite3.Connection]:
        """One write transaction (``BEGIN IMMEDIATE`` ... ``COMMIT``, ``ROLLBACK`` on error), as :meth:`reading`."""
        return self._write()

    def _in_transaction_hook(self, operation: str, set_id: str) -> None:
        """Called inside a write transaction just before ``COMMIT`` (a no-op; tests override it)."""

    def _initialise(self) -> None:
        """Make a new file incremental-vacuum, switch to WAL, check the application id and run pending migrations."""
        deadline = time.monotonic() + self.busy_timeout
        while True:
            try:
                with self._connect() as conn:
                    if conn.execute("PRAGMA page_count").fetchone()[0] == 0:
                        # a new (empty) file: only now, before its header is written, can auto_vacuum be chosen
                        conn.execute(f"PRAGMA auto_vacuum = {AUTO_VACUUM_INCREMENTAL}")
                    mode = conn.execute("PRAGMA journal_mode").fetchone()[0]
                    if str(mode).lower() != "wal":
                        mode = conn.execute("PRAGMA journal_mode = WAL").fetchone()[0]
                        if str(mode).lower() != "wal":
                            raise PatternStoreError(f"cannot switch {self.path} to WAL journal mode (got {mode!r})")
                    conn.execute("BEGIN IMMEDIATE")
                    try:
                        migrate(conn, self.path)
                    except BaseException:
                        conn.execute("ROLLBACK")
                        raise
                    conn.execute("COMMIT")
                return
            except PatternStoreError as exc:
                # switching the journal mode can fail with "locked" without honouring the
                # busy handler while another process opens the same new file; retry.
                cause = exc.__cause__
                if isinstance(cause, sqlite3.OperationalError) and _is_locked(cause) and time.monotonic() < deadline:
                    time.sleep(0.01)
                    continue
                raise

    # -- writes ---------------------------------------------------------------------
    def save(self, pattern_set: PatternSet, *, conn: sqlite3.Connection | None = None) -> PatternSet:
        """Store a pattern set in one transaction.

        Parameters
        ----------
        pattern_set : PatternSet
            The set to store. ``id`` may be ``None`` (a uuid4 hex is assigned);
            ``created_at`` is always set by the store.
        conn : sqlite3.Connection or None
            A write transaction of this file (:meth:`writing`) to write the set in, with the caller's other
            rows (a service's job that moves to ``done`` with it): the caller then commits, and the set is
            stored only if everything is. ``None``: a transaction of its own.

        Returns
        -------
        PatternSet
            A new object as it is stored: with ``id`` and ``created_at`` set, ``params``
            normalised through JSON, ``j1_values`` as floats. The argument is not modified.

        Raises
        ------
        InvalidPatternSet
            (a ``ValueError``) for an unknown channel, non-finite ``c``, empty or
            non-finite arrays, non-JSON ``params``, ...; nothing is written.
        PatternSetExists
            (a ``ValueError``) if the id is already stored; nothing is written.
        PatternStoreError
            If the write lock could not be obtained within ``busy_timeout``.
        """
        prep = prepare(pattern_set)
        set_id = pattern_set.id or uuid.uuid4().hex
        own = conn is None
        try:
            with self._write() if conn is None else contextlib.nullcontext(conn) as conn:
                created_at = _utc_now()  # taken under the write lock: agrees with commit order
                conn.execute(
                    "INSERT INTO pattern_sets (id, kind, channel, c, j1_values, wavelet, params, model_version, "
                    "created_at, arrays_meta, arrays_sha256, arrays_blob) VALUES (?,?,?,?,?,?,?,?,?,?,?,?)",
                    (
                        set_id,
                        prep.kind,
                        prep.channel,
                        prep.c,
                        prep.j1_text,
                        prep.wavelet,
                        prep.params_text,
                        prep.model_version,
                        created_at,
                        prep.meta_text,
                        prep.sha256,
                        prep.blob,
                    ),
                )
                self._in_transaction_hook("save", set_id)
        except sqlite3.IntegrityError as exc:
            raise PatternSetExists(
                f"a pattern set with id {set_id!r} already exists in {self.path}; "
                "leave id None to get a new one, or delete the old set first"
            ) from exc
        logger.info(
            "%s pattern set %s (kind=%s channel=%s c=%g model=%s, %d bytes) to %s",
            "saved" if own else "wrote (committed with the caller's transaction)",
            set_id, prep.kind, prep.channel, prep.c, prep.model_version, len(prep.blob), self.path,
        )  # fmt: skip
        return PatternSet(
            id=set_id,
            kind=prep.kind,
            channel=prep.channel,
            c=prep.c,
            j1_values=list(prep.j1_values),
            wavelet=prep.wavelet,
            params=prep.params,
            model_version=prep.model_version,
            created_at=created_at,
            arrays={name: arr.copy(order="K") for name, arr in prep.arrays.items()},
        )

    def delete(self, set_id: str) -> None:
        """Delete a pattern set in one transaction.

        Parameters
        ----------
        set_id : str
            Id of the set.

        Raises
        ------
        PatternSetNotFound
            If no set has this id (nothing is changed).
        """
        with self._write() as conn:
            cur = conn.execute("DELETE FROM pattern_sets WHERE id = ?", (str(set_id),))
            if cur.rowcount == 0:
                raise PatternSetNotFound(self._not_found(set_id))
            self._in_transaction_hook("delete", str(set_id))
        logger.info("deleted pattern set %s from %s", set_id, self.path)

    # -- reads ------------------------------------------------------------------------
    def _not_found(self, set_id: object) -> str:
        return f"no pattern set with id {set_id!r} in {self.path}; list() shows the stored ids"

    def _metadata(self, row: tuple[Any, ...], *json_columns: str) -> dict[str, Any]:
        """Common metadata of a row (its first nine columns), plus extra JSON columns decoded."""
        (set_id, kind, channel, c, j1_text, wavelet, params_text, model_version, created_at) = row[:9]
        try:
            j1 = json.loads(j1_text)
            params = json.loads(params_text)
            extra = [json.loads(t) for t in json_columns]
        except ValueError as exc:
            raise CorruptPatternSet(f"pattern set {set_id!r} in {self.path}: unreadable metadata: {exc}") from exc
        return dict(
            id=set_id,
            kind=kind,
            channel=channel,
            c=float(c),
            j1_values=[float(v) for v in j1],
            wavelet=wavelet,
            params=params,
            model_version=model_version,
            created_at=created_at,
            _extra=extra,
        )

    def _row_to_set(self, row: tuple[Any, ...]) -> PatternSet:
        meta = self._metadata(row)
        meta.pop("_extra")
        sha, blob = row[9], row[10]
        return PatternSet(**meta, arrays=decode_arrays(bytes(blob), sha, meta["id"], self.path))

    def get(self, set_id: str) -> PatternSet:
        """Read one pattern set with its arrays.

        Parameters
        ----------
        set_id : str
            Id of the set.

        Returns
        -------
        PatternSet

        Raises
        ------
        PatternSetNotFound
            If no set has this id.
        CorruptPatternSet
            If the stored arrays fail their SHA-256 check or cannot be decoded.
        """
        with self._connect() as conn:
            row = conn.execute(f"SELECT {FULL_COLUMNS} FROM pattern_sets WHERE id = ?", (str(set_id),)).fetchone()
        if row is None:
            raise PatternSetNotFound(self._not_found(set_id))
        return self._row_to_set(row)

    def list(
        self,
        channel: str | None = None,
        c: float | None = None,
        kind: str | None = None,
        *,
        model_version: str | None = None,
    ) -> builtins.list[PatternSetSummary]:
        """List stored pattern sets (metadata only), newest first.

        Parameters
        ----------
        channel : str or None
            Only sets of this channel (must be one of ``CHANNELS``).
        c : float or None
            Only sets whose ``c`` equals this value [pu] (to a relative 1e-9).
        kind : str or None
            Only sets of this identifier kind.
        model_version : str or None
            Only sets of this reference-model version.

        Returns
        -------
        list of PatternSetSummary
            Newest (most recently saved) first.

        Raises
        ------
        InvalidPatternSet
            For an unknown channel or a non-finite ``c``.
        """
        where, args = self._filters(channel=channel, kind=kind, model_version=model_version)
        if c is not None:
            cv = require_c(c)
            where.append("abs(c - ?) <= ?")
            args += [cv, 1e-9 * max(abs(cv), 1e-3)]
        sql = f"SELECT {SUMMARY_COLUMNS} FROM pattern_sets"
        if where:
            sql += " WHERE " + " AND ".join(where)
        sql += " ORDER BY seq DESC"
        with self._connect() as conn:
            rows = conn.execute(sql, args).fetchall()
        return [self._row_to_summary(row) for row in rows]

    def _filters(
        self, *, channel: str | None, kind: str | None, model_version: str | None
    ) -> tuple[builtins.list[str], builtins.list[Any]]:
        where: builtins.list[str] = []
        args: builtins.list[Any] = []
        if channel is not None:
            where.append("channel = ?")
            args.append(require_channel(channel))
        if kind is not None:
            where.append("kind = ?")
            args.append(kind)
        if model_version is not None:
            where.append("model_version = ?")
            args.append(model_version)
        return where, args

    def _row_to_summary(self, row: tuple[Any, ...]) -> PatternSetSummary:
        meta_text, size = row[9], row[10]
        fields_ = self._metadata(row, meta_text)
        (arrays_meta,) = fields_.pop("_extra")
        return PatternSetSummary(
            **fields_,
            array_shapes={name: tuple(m["shape"]) for name, m in arrays_meta.items()},
            array_dtypes={name: m["dtype"] for name, m in arrays_meta.items()},
            size_bytes=int(size),
        )

    def __len__(self) -> int:
        with self._connect() as conn:
            return int(conn.execute("SELECT count(*) FROM pattern_sets").fetchone()[0])

    def __contains__(self, set_id: object) -> bool:
        with self._connect() as conn:
            return conn.execute("SELECT 1 FROM pattern_sets WHERE id = ?", (str(set_id),)).fetchone() is not None

    def check(self) -> builtins.list[str]:
        """Check the whole database: SQLite's ``integrity_check`` and every set's checksum.

        Returns
        -------
        list of str
            Problems found; empty if the store is sound.
        """
        problems: builtins.list[str] = []
        with self._connect() as conn:
            result = [r[0] for r in conn.execute("PRAGMA integrity_check").fetchall()]
            if result != ["ok"]:
                problems += [f"integrity_check: {r}" for r in result]
            for set_id, sha, blob in conn.execute("SELECT id, arrays_sha256, arrays_blob FROM pattern_sets"):
                if sha256(bytes(blob)) != sha:
                    problems.append(f"pattern set {set_id!r}: arrays fail their SHA-256 check")
        return problems

    # -- size and compaction ---------------------------------------------------------------
    def size_bytes(self) -> int:
        """Size of the database file plus its ``-wal`` file [bytes] (what the store takes on disk, but ``-shm``)."""
        total = 0
        for path in (self.path, self.path.with_name(self.path.name + "-wal")):
            with contextlib.suppress(FileNotFoundError):
                total += path.stat().st_size
        return total

    def compact(self) -> Compaction:
        """Give the pages that deletions freed back to the file system, so that the file shrinks.

        An incremental file (every file this code creates) runs ``PRAGMA incremental_vacuum``; a file created
        with ``auto_vacuum = NONE`` is rewritten once by ``VACUUM``, which also makes it incremental (see the
        module docstring). A ``wal_checkpoint(TRUNCATE)`` follows. Nothing is done when no page is free.

        Returns
        -------
        Compaction
            The method used and the sizes before and after [bytes].

        Raises
        ------
        PatternStoreError
            The write lock was not obtained within ``busy_timeout`` (another writer held it), or SQLite failed
            (e.g. no disk space for the ``VACUUM``'s copy; the file is then unchanged).

        Notes
        -----
        Neither statement may run inside a transaction: this connection runs them in autocommit, and other
        connections' writes wait for them (up to their busy timeout), as for any write. A ``VACUUM`` of a large
        file takes the time of copying it.
        """
        before = self.size_bytes()
        with self._connect() as conn:
            page_size = int(conn.execute("PRAGMA page_size").fetchone()[0])
            free = int(conn.execute("PRAGMA freelist_count").fetchone()[0])
            auto_vacuum = int(conn.execute("PRAGMA auto_vacuum").fetchone()[0])
            if free == 0:
                method = "none"
            elif auto_vacuum == AUTO_VACUUM_INCREMENTAL:
                method = "incremental_vacuum"
                # executescript steps the pragma to its end (execute() would free one page per call)
                conn.executescript("PRAGMA incremental_vacuum;")
            else:
                method = "vacuum"
                conn.execute(f"PRAGMA auto_vacuum = {AUTO_VACUUM_INCREMENTAL}")  # takes effect with the VACUUM
                conn.execute("VACUUM")
            busy = conn.execute("PRAGMA wal_checkpoint(TRUNCATE)").fetchone()[0]
        result = Compaction(
            method=method,
            bytes_before=before,
            bytes_after=self.size_bytes(),
            free_pages_before=free,
            page_size=page_size,
            checkpointed=busy == 0,
        )
        logger.info(
            "compacted %s (%s): %d free pages of %d bytes; %d -> %d bytes%s",
            self.path, method, free, page_size, result.bytes_before, result.bytes_after,
            "" if result.checkpointed else " (checkpoint held back by a reader: the file shrinks later)",
        )  # fmt: skip
        return result
