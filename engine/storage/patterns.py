"""Durable store for trained identifiers ("pattern sets").

A *pattern set* is what training an identifier produces: a little metadata
(identifier kind, channel, apparent-viscosity group ``c`` [pu], the J1 grid
[kg m^2] it was trained on, the wavelet, hyper-parameters, the reference-model
version) plus a few named numpy arrays (the patterns, the zone widths, scaler
constants, ...).

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
* the array blob is an in-memory ``.npz`` written with ``allow_pickle=False``
  (bit-exact, dtype and shape preserved, never pickle) stored next to its
  SHA-256, which is checked on every read;
* the schema carries a version (``PRAGMA user_version``) and an application id;
  :data:`MIGRATIONS` upgrades older files when a store is opened.

WAL needs shared memory between the processes using the file, so the database
must live on a local file system (not NFS/SMB).
"""

from __future__ import annotations

import builtins
import contextlib
import hashlib
import io
import json
import logging
import math
import os
import re
import sqlite3
import time
import uuid
import zipfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from engine.constants import CHANNELS, MODEL_VERSION

logger = logging.getLogger(__name__)

__all__ = [
    "DEFAULT_STORE_PATH",
    "MIGRATIONS",
    "SCHEMA_VERSION",
    "STORE_PATH_ENV",
    "CorruptPatternSet",
    "InvalidPatternSet",
    "PatternSet",
    "PatternSetExists",
    "PatternSetNotFound",
    "PatternSetSummary",
    "PatternStore",
    "PatternStoreError",
    "default_store_path",
]

#: Environment variable that overrides the default database path.
STORE_PATH_ENV = "BACKLASH_DB_PATH"
#: Database path used when neither an explicit path nor ``STORE_PATH_ENV`` is given
#: (relative to the working directory).
DEFAULT_STORE_PATH = Path("data") / "patterns.sqlite3"
#: ``PRAGMA application_id`` marking a file as a backlash pattern store ("BKLS").
APPLICATION_ID = 0x424B4C53

_ID_RE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
_ARRAY_NAME_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,63}$")
_ARRAY_KINDS = "biufc"  # bool, signed/unsigned int, float, complex


# --- errors ------------------------------------------------------------------
class PatternStoreError(Exception):
    """Base class for pattern-store failures (open, lock, corruption)."""


class PatternSetNotFound(PatternStoreError, KeyError):
    """Raised when no pattern set has the requested id."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else "pattern set not found"


class InvalidPatternSet(ValueError):
    """Raised by :meth:`PatternStore.save` for malformed input; the message says what to fix."""


class PatternSetExists(PatternStoreError, ValueError):
    """Raised when saving a pattern set whose id is already stored."""


class CorruptPatternSet(PatternStoreError):
    """Raised when a stored pattern set fails its checksum or cannot be decoded."""


# --- data classes --------------------------------------------------------------
@dataclass(kw_only=True)
class PatternSet:
    """A trained identifier: metadata plus named numpy arrays.

    Parameters
    ----------
    id : str or None
        Identifier (uuid4 hex). ``None`` lets the store assign one on save.
    kind : str
        Identifier kind, e.g. ``"paper"`` or ``"template"``.
    channel : str
        Channel the identifier works on, one of :data:`engine.constants.CHANNELS`.
    c : float
        Apparent-viscosity group the set was trained for [pu].
    j1_values : list of float
        Motor-side inertias J1 the set was trained on [kg m^2].
    wavelet : str
        Wavelet name used for the features (e.g. ``"sym5"``).
    params : dict
        JSON-able hyper-parameters (learning_rate, delta1, max_epochs, effects, ...).
        Stored as JSON, so tuples come back as lists.
    model_version : str
        Reference-model version the set was trained on.
    created_at : str or None
        ISO-8601 UTC time of the save, set by the store (any value given is replaced).
    arrays : dict of str to ndarray
        Named numeric arrays, e.g. ``"patterns"`` (6, 15), ``"widths"`` (6,) [m],
        scaler constants. Round-trip bit-exactly with dtype and shape.

    Notes
    -----
    ``==`` compares metadata and arrays bit-exactly (dtype, shape and bytes).
    """

    id: str | None = None
    kind: str
    channel: str
    c: float
    j1_values: list[float]
    wavelet: str
    params: dict[str, Any] = field(default_factory=dict)
    model_version: str = MODEL_VERSION
    created_at: str | None = None
    arrays: dict[str, np.ndarray] = field(default_factory=dict)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PatternSet):
            return NotImplemented
        return self.summary_fields() == other.summary_fields() and _arrays_equal(self.arrays, other.arrays)

    __hash__ = None  # type: ignore[assignment]  # mutable

    def __repr__(self) -> str:
        shapes = {name: np.asarray(a) for name, a in self.arrays.items()}
        arrays = ", ".join(f"{name}: {a.dtype.str}{a.shape}" for name, a in shapes.items())
        return (
            f"PatternSet(id={self.id!r}, kind={self.kind!r}, channel={self.channel!r}, c={self.c!r}, "
            f"j1_values={self.j1_values!r}, wavelet={self.wavelet!r}, params={self.params!r}, "
            f"model_version={self.model_version!r}, created_at={self.created_at!r}, arrays={{{arrays}}})"
        )

    def summary_fields(self) -> tuple[Any, ...]:
        """Return the metadata as a tuple (everything but the arrays).

        Returns
        -------
        tuple
            ``(id, kind, channel, c, j1_values, wavelet, params, model_version, created_at)``.
        """
        return (
            self.id,
            self.kind,
            self.channel,
            self.c,
            list(self.j1_values),
            self.wavelet,
            self.params,
            self.model_version,
            self.created_at,
        )


@dataclass(frozen=True, kw_only=True)
class PatternSetSummary:
    """Metadata of a stored pattern set, without its arrays (see :class:`PatternSet`).

    Parameters
    ----------
    id, kind, channel, c, j1_values, wavelet, params, model_version, created_at
        As in :class:`PatternSet`.
    array_shapes : dict of str to tuple of int
        Shape of each stored array.
    array_dtypes : dict of str to str
        Dtype (``numpy.dtype.str``, e.g. ``"<f8"``) of each stored array.
    size_bytes : int
        Size of the stored array blob [bytes].
    """

    id: str
    kind: str
    channel: str
    c: float
    j1_values: list[float]
    wavelet: str
    params: dict[str, Any]
    model_version: str
    created_at: str
    array_shapes: dict[str, tuple[int, ...]]
    array_dtypes: dict[str, str]
    size_bytes: int


def _arrays_equal(a: Mapping[str, np.ndarray], b: Mapping[str, np.ndarray]) -> bool:
    if set(a) != set(b):
        return False
    for name in a:
        x, y = np.asarray(a[name]), np.asarray(b[name])
        if x.dtype != y.dtype or x.shape != y.shape or x.tobytes() != y.tobytes():
            return False
    return True


# --- schema and migrations -------------------------------------------------------
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


#: Migration hook: ``MIGRATIONS[v]`` upgrades a database from schema version ``v`` to
#: ``v + 1`` inside the opening transaction. Append a function to change the schema;
#: :data:`SCHEMA_VERSION` follows.
MIGRATIONS: list[Callable[[sqlite3.Connection], None]] = [_migrate_0_to_1]
#: Schema version written by this code (``PRAGMA user_version``).
SCHEMA_VERSION = len(MIGRATIONS)

_SUMMARY_COLUMNS = (
    "id, kind, channel, c, j1_values, wavelet, params, model_version, created_at, arrays_meta, length(arrays_blob)"
)


def default_store_path() -> Path:
    """Return the database path to use when none is given.

    Returns
    -------
    Path
        ``$BACKLASH_DB_PATH`` if set, else :data:`DEFAULT_STORE_PATH`.
    """
    env = os.environ.get(STORE_PATH_ENV)
    return Path(env) if env else DEFAULT_STORE_PATH


def _utc_now() -> str:
    return datetime.now(UTC).isoformat(timespec="microseconds")


def _is_locked(exc: sqlite3.Error) -> bool:
    msg = str(exc).lower()
    return "locked" in msg or "busy" in msg


# --- validation and (de)serialisation ----------------------------------------------
def _require_channel(channel: object) -> str:
    if not isinstance(channel, str) or channel not in CHANNELS:
        raise InvalidPatternSet(f"unknown channel {channel!r}; use one of: {', '.join(CHANNELS)}")
    return channel


def _require_c(c: object, what: str = "c") -> float:
    if isinstance(c, bool) or not isinstance(c, (int, float, np.integer, np.floating)):
        raise InvalidPatternSet(f"{what} must be a real number [pu], got {type(c).__name__}")
    value = float(c)
    if not math.isfinite(value):
        raise InvalidPatternSet(f"{what} must be finite [pu], got {value!r}")
    return value


def _require_text(value: object, name: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise InvalidPatternSet(f"{name} must be a non-empty string, got {value!r}")
    return value


def _to_json(value: object, name: str) -> tuple[str, Any]:
    """Serialise ``value`` to canonical JSON; return the text and its parsed (normalised) form."""
    try:
        text = json.dumps(value, sort_keys=True, allow_nan=False, separators=(",", ":"))
    except (TypeError, ValueError) as exc:
        raise InvalidPatternSet(
            f"{name} must be JSON-serialisable (str keys; str, int, float, bool, None, list, dict values; "
            f"finite floats; convert numpy scalars/arrays with .item()/.tolist()): {exc}"
        ) from exc
    return text, json.loads(text)


def _validate_arrays(arrays: object) -> dict[str, np.ndarray]:
    if not isinstance(arrays, Mapping) or not arrays:
        raise InvalidPatternSet('arrays must be a non-empty dict of name -> numpy array, e.g. {"patterns": ...}')
    clean: dict[str, np.ndarray] = {}
    for name, value in arrays.items():
        if not isinstance(name, str) or not _ARRAY_NAME_RE.match(name):
            raise InvalidPatternSet(
                f"array name {name!r} is not allowed; use 1-64 characters from [A-Za-z0-9_.-] "
                "not starting with '.' or '-'"
            )
        arr = np.asarray(value)
        if arr.dtype.kind not in _ARRAY_KINDS:
            raise InvalidPatternSet(
                f"array {name!r} has dtype {arr.dtype}; only bool, integer, float and complex arrays can be stored"
            )
        if arr.size == 0:
            raise InvalidPatternSet(f"array {name!r} is empty (shape {arr.shape}); store at least one value")
        if arr.dtype.kind in "fc":
            finite = np.isfinite(arr)
            if not finite.all():
                bad = np.argwhere(~finite)[0]
                where = tuple(int(i) for i in bad)
                raise InvalidPatternSet(
                    f"array {name!r} holds a non-finite value ({arr[where]!r}) at index {where}; "
                    "training must produce finite values"
                )
        clean[name] = arr
    return clean


def _encode_arrays(arrays: Mapping[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, allow_pickle=False, **arrays)
    return buf.getvalue()


def _decode_arrays(blob: bytes, expected_sha256: str, set_id: str, path: Path) -> dict[str, np.ndarray]:
    digest = hashlib.sha256(blob).hexdigest()
    if digest != expected_sha256:
        logger.error("pattern set %s in %s fails its checksum", set_id, path)
        raise CorruptPatternSet(
            f"pattern set {set_id!r} in {path} is corrupt: its arrays' SHA-256 is {digest}, "
            f"expected {expected_sha256}; delete it and train it again"
        )
    try:
        with np.load(io.BytesIO(blob), allow_pickle=False) as npz:
            return {name: npz[name] for name in npz.files}
    except (ValueError, OSError, zipfile.BadZipFile, KeyError) as exc:
        raise CorruptPatternSet(f"pattern set {set_id!r} in {path}: cannot decode its arrays: {exc}") from exc


@dataclass(frozen=True)
class _Prepared:
    """A validated pattern set ready to insert."""

    kind: str
    channel: str
    c: float
    j1_text: str
    j1_values: list[float]
    wavelet: str
    params_text: str
    params: dict[str, Any]
    model_version: str
    arrays: dict[str, np.ndarray]
    meta_text: str
    sha256: str
    blob: bytes


def _prepare(ps: PatternSet) -> _Prepared:
    if not isinstance(ps, PatternSet):
        raise InvalidPatternSet(f"save() takes a PatternSet, got {type(ps).__name__}")
    if ps.id is not None and (not isinstance(ps.id, str) or not _ID_RE.match(ps.id)):
        raise InvalidPatternSet(
            f"id {ps.id!r} is not allowed; leave it None (the store assigns a uuid4 hex) "
            "or use 1-64 characters from [A-Za-z0-9_-]"
        )
    kind = _require_text(ps.kind, "kind")
    channel = _require_channel(ps.channel)
    c = _require_c(ps.c)
    wavelet = _require_text(ps.wavelet, "wavelet")
    model_version = _require_text(ps.model_version, "model_version")

    if isinstance(ps.j1_values, (str, bytes)) or not isinstance(ps.j1_values, (Sequence, np.ndarray)):
        raise InvalidPatternSet(f"j1_values must be a list of inertias [kg m^2], got {type(ps.j1_values).__name__}")
    if len(ps.j1_values) == 0:
        raise InvalidPatternSet("j1_values is empty; give the inertias J1 [kg m^2] the set was trained on")
    j1: list[float] = []
    for v in ps.j1_values:
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise InvalidPatternSet(f"j1_values must hold numbers [kg m^2], got {v!r}")
        if not math.isfinite(float(v)) or float(v) <= 0.0:
            raise InvalidPatternSet(f"j1_values must hold finite positive inertias [kg m^2], got {v!r}")
        j1.append(float(v))

    if not isinstance(ps.params, Mapping):
        raise InvalidPatternSet(f"params must be a dict of hyper-parameters, got {type(ps.params).__name__}")
    params_text, params = _to_json(dict(ps.params), "params")
    j1_text, _ = _to_json(j1, "j1_values")

    arrays = _validate_arrays(ps.arrays)
    meta = {name: {"dtype": arr.dtype.str, "shape": list(arr.shape)} for name, arr in arrays.items()}
    meta_text, _ = _to_json(meta, "arrays metadata")
    blob = _encode_arrays(arrays)
    return _Prepared(
        kind=kind,
        channel=channel,
        c=c,
        j1_text=j1_text,
        j1_values=j1,
        wavelet=wavelet,
        params_text=params_text,
        params=params,
        model_version=model_version,
        arrays=arrays,
        meta_text=meta_text,
        sha256=hashlib.sha256(blob).hexdigest(),
        blob=blob,
    )


# --- the store -------------------------------------------------------------------
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

    def _in_transaction_hook(self, operation: str, set_id: str) -> None:
        """Called inside a write transaction just before ``COMMIT`` (a no-op; tests override it)."""

    def _initialise(self) -> None:
        """Switch to WAL, check the application id and run pending migrations."""
        deadline = time.monotonic() + self.busy_timeout
        while True:
            try:
                with self._connect() as conn:
                    mode = conn.execute("PRAGMA journal_mode").fetchone()[0]
                    if str(mode).lower() != "wal":
                        mode = conn.execute("PRAGMA journal_mode = WAL").fetchone()[0]
                        if str(mode).lower() != "wal":
                            raise PatternStoreError(f"cannot switch {self.path} to WAL journal mode (got {mode!r})")
                    conn.execute("BEGIN IMMEDIATE")
                    try:
                        self._migrate(conn)
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

    def _migrate(self, conn: sqlite3.Connection) -> None:
        app_id = conn.execute("PRAGMA application_id").fetchone()[0]
        version = conn.execute("PRAGMA user_version").fetchone()[0]
        if app_id not in (0, APPLICATION_ID):
            raise PatternStoreError(
                f"{self.path} is a SQLite database of another application (application_id {app_id})"
            )
        if app_id == 0:
            tables = conn.execute("SELECT count(*) FROM sqlite_master").fetchone()[0]
            if version != 0 or tables:
                raise PatternStoreError(
                    f"{self.path} is a SQLite database but not a pattern store; choose another path"
                )
        target = len(MIGRATIONS)
        if version > target:
            raise PatternStoreError(
                f"{self.path} has schema version {version}, newer than this code supports ({target}); upgrade backlash"
            )
        for v in range(version, target):
            logger.info("migrating pattern store %s from schema %d to %d", self.path, v, v + 1)
            MIGRATIONS[v](conn)
            conn.execute(f"PRAGMA user_version = {v + 1}")
        if app_id == 0:
            conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")

    # -- writes ---------------------------------------------------------------------
    def save(self, pattern_set: PatternSet) -> PatternSet:
        """Store a pattern set in one transaction.

        Parameters
        ----------
        pattern_set : PatternSet
            The set to store. ``id`` may be ``None`` (a uuid4 hex is assigned);
            ``created_at`` is always set by the store.

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
        prep = _prepare(pattern_set)
        set_id = pattern_set.id or uuid.uuid4().hex
        try:
            with self._write() as conn:
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
            "saved pattern set %s (kind=%s channel=%s c=%g model=%s, %d bytes) to %s",
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
        return PatternSet(**meta, arrays=_decode_arrays(bytes(blob), sha, meta["id"], self.path))

    _FULL_COLUMNS = (
        "id, kind, channel, c, j1_values, wavelet, params, model_version, created_at, arrays_sha256, arrays_blob"
    )

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
            row = conn.execute(f"SELECT {self._FULL_COLUMNS} FROM pattern_sets WHERE id = ?", (str(set_id),)).fetchone()
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
            cv = _require_c(c)
            where.append("abs(c - ?) <= ?")
            args += [cv, 1e-9 * max(abs(cv), 1e-3)]
        sql = f"SELECT {_SUMMARY_COLUMNS} FROM pattern_sets"
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
            args.append(_require_channel(channel))
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

    def find_nearest(
        self,
        channel: str,
        c: float,
        kind: str | None = None,
        model_version: str = MODEL_VERSION,
    ) -> PatternSet | None:
        """Return the set of ``channel`` whose ``c`` is nearest to the requested one.

        Parameters
        ----------
        channel : str
            Channel, one of ``CHANNELS``.
        c : float
            Apparent-viscosity group wanted [pu].
        kind : str or None
            Only sets of this identifier kind (any kind if ``None``).
        model_version : str
            Only sets of this reference-model version (sets of other versions are
            never returned).

        Returns
        -------
        PatternSet or None
            The nearest set, the most recently saved one among equally near sets;
            ``None`` if there is no candidate.

        Raises
        ------
        InvalidPatternSet
            For an unknown channel or a non-finite ``c``.
        CorruptPatternSet
            If the chosen set fails its checksum.
        """
        cv = _require_c(c)
        version = _require_text(model_version, "model_version")
        where, args = self._filters(channel=_require_channel(channel), kind=kind, model_version=version)
        sql = (
            f"SELECT {self._FULL_COLUMNS} FROM pattern_sets WHERE {' AND '.join(where)} "
            "ORDER BY abs(c - ?) ASC, seq DESC LIMIT 1"
        )
        with self._connect() as conn:
            row = conn.execute(sql, [*args, cv]).fetchone()
        return None if row is None else self._row_to_set(row)

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
                if hashlib.sha256(bytes(blob)).hexdigest() != sha:
                    problems.append(f"pattern set {set_id!r}: arrays fail their SHA-256 check")
        return problems
