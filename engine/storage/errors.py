"""The pattern store's exceptions.

Every failure of the store itself (open, lock, corruption) is a :class:`PatternStoreError`;
malformed input to :meth:`~engine.storage.PatternStore.save` is an :class:`InvalidPatternSet`
(a ``ValueError``, so it can be reported as the caller's mistake).
"""

from __future__ import annotations

__all__ = [
    "CorruptPatternSet",
    "InvalidPatternSet",
    "PatternSetExists",
    "PatternSetNotFound",
    "PatternStoreError",
]


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
