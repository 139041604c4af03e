"""The sim-to-real gap diagnosis (issue 4) as the service sees it."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from app.services.errors import NotAvailableError
from engine.records import Record

NOT_AVAILABLE = (
    "the sim-to-real gap diagnosis is not available yet in this version (the engine's diagnosis is not wired "
    "into the service); simulate (POST /v1/simulate) and identify (POST /v1/identify) work"
)


def diagnose(record: Record, effects: Sequence[str] | None = None) -> dict[str, Any]:
    """Diagnose the gap between ``record`` and the model; the response format is defined by issue 4.

    TODO(engine): call the engine's diagnosis here (``engine.diagnosis``, issue 4) and
    return its JSON-ready result; ``effects`` restricts the candidate catalogue.
    Until then this raises :class:`NotAvailableError` (HTTP 501, CLI exit 2).
    """
    raise NotAvailableError(NOT_AVAILABLE)
