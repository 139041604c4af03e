"""Persistence for trained identifiers ("pattern sets").

One idea per module: the exceptions (:mod:`~engine.storage.errors`), the data model
(:mod:`~engine.storage.models`), the SQLite schema and its migrations
(:mod:`~engine.storage.schema`), the array codec (:mod:`~engine.storage.codec`), input
validation (:mod:`~engine.storage.validation`), the default path
(:mod:`~engine.storage.paths`) and the store itself (:mod:`~engine.storage.store`).
Choosing which stored set identifies a record is not storage:
:mod:`engine.identification.selection`.
"""

from engine.storage.errors import (
    CorruptPatternSet,
    InvalidPatternSet,
    PatternSetExists,
    PatternSetNotFound,
    PatternStoreError,
)
from engine.storage.models import PatternSet, PatternSetSummary
from engine.storage.paths import DEFAULT_STORE_PATH, STORE_PATH_ENV, default_store_path
from engine.storage.schema import MIGRATIONS, SCHEMA_VERSION
from engine.storage.store import Compaction, PatternStore

__all__ = [
    "DEFAULT_STORE_PATH",
    "MIGRATIONS",
    "SCHEMA_VERSION",
    "STORE_PATH_ENV",
    "Compaction",
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
