"""Persistence for trained identifiers ("pattern sets"); see :mod:`engine.storage.patterns`."""

from engine.storage.patterns import (
    DEFAULT_STORE_PATH,
    MIGRATIONS,
    SCHEMA_VERSION,
    STORE_PATH_ENV,
    CorruptPatternSet,
    InvalidPatternSet,
    PatternSet,
    PatternSetExists,
    PatternSetNotFound,
    PatternSetSummary,
    PatternStore,
    PatternStoreError,
    default_store_path,
)

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
