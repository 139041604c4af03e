"""Errors of the record boundary: what is wrong with a record, in words that say what to fix."""

from __future__ import annotations

__all__ = ["ProtocolError", "RecordError"]


class RecordError(ValueError):
    """Raised when a record is malformed; the message says what to fix."""


class ProtocolError(RecordError):
    """Raised when a well-formed record cannot hold the backlash test (MODEL.md section 2) or cannot be read as one.

    For example a sample interval outside 10 us - 1 ms, too little time around the event, or an
    event that cannot be located from the channels given.
    """
