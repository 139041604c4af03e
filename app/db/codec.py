"""How the service's tables hold timestamps and JSON documents."""

from __future__ import annotations

import json
import zlib
from datetime import UTC, datetime
from typing import Any


def now() -> datetime:
    """The current instant, timezone-aware UTC."""
    return datetime.now(UTC)


def to_text(moment: datetime | None) -> str | None:
    """ISO 8601 in UTC (``None`` stays ``None``); naive datetimes are refused, never assumed UTC."""
    if moment is None:
        return None
    if moment.tzinfo is None:
        raise ValueError("a timestamp without a UTC offset cannot be stored unambiguously")
    return moment.astimezone(UTC).isoformat(timespec="microseconds")


def from_text(text: str | None) -> datetime | None:
    """The datetime of :func:`to_text`'s text."""
    return None if text is None else datetime.fromisoformat(text)


def pack(document: Any) -> bytes:
    """A JSON-able document as zlib-compressed UTF-8 JSON."""
    return zlib.compress(json.dumps(document, separators=(",", ":"), allow_nan=False).encode(), 6)


def unpack(blob: bytes | None) -> Any:
    """The document of :func:`pack` (``None`` stays ``None``)."""
    return None if blob is None else json.loads(zlib.decompress(blob))
