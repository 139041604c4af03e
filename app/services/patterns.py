"""Identifiers and stored pattern sets, as the service presents them.

Training and rebuilding identifiers is the engine's
(:mod:`engine.identification.training`); this module turns its errors into the
service's and describes stored sets as JSON.
"""

from __future__ import annotations

import inspect
import sqlite3
from collections.abc import Callable
from typing import Any

from app.db.jobs import UNFINISHED, Job
from app.services.errors import IncompatibleError, InvalidInputError, StorageFullError, some_names
from engine.identification import training as engine_training
from engine.storage import PatternSet, PatternSetSummary


def check_identifier(kind: str, channel: str, params: dict[str, Any]) -> None:
    """Raise :class:`InvalidInputError` if the engine cannot build this identifier (unknown kind or parameter, or a
    value it would refuse only once training: a wavelet PyWavelets lacks, a network too large, ...)."""
    cls = engine_training.IDENTIFIERS.get(kind)
    if cls is not None:  # the engine's message would list every unknown name, however many a request sends
        accepted = set(inspect.signature(cls).parameters) - {"channel"}
        unknown = set(params) - accepted
        if unknown:
            raise InvalidInputError(
                f"identifier {kind!r} has no parameter(s) {some_names(unknown)}; accepted: {', '.join(sorted(accepted))}"
            )
    try:
        engine_training.make_identifier(kind, channel, **params).validate_params()
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(str(exc)) from None


def identifier_from_pattern_set(pattern_set: PatternSet) -> Any:
    """Rebuild the fitted identifier stored in ``pattern_set`` (:class:`IncompatibleError` if it cannot be)."""
    try:
        return engine_training.identifier_from_pattern_set(pattern_set)
    except (TypeError, ValueError) as exc:
        raise IncompatibleError(f"pattern set {pattern_set.id!r} cannot be loaded: {exc}; train it again") from None


def describe(pattern_set: PatternSet | PatternSetSummary) -> dict[str, Any]:
    """A stored set's metadata, JSON-ready (arrays listed by name and shape)."""
    if isinstance(pattern_set, PatternSet):
        shapes = {name: list(arr.shape) for name, arr in pattern_set.arrays.items()}
    else:
        shapes = {name: list(shape) for name, shape in pattern_set.array_shapes.items()}
    return {
        "id": pattern_set.id,
        "kind": pattern_set.kind,
        "channel": pattern_set.channel,
        "c": pattern_set.c,
        "J1_values": list(pattern_set.j1_values),
        "wavelet": pattern_set.wavelet,
        "params": pattern_set.params,
        "model_version": pattern_set.model_version,
        "created_at": pattern_set.created_at,
        "arrays": shapes,
    }


def pattern_set_room(limit: int) -> Callable[[sqlite3.Connection, Job], None]:
    """A ``with_rows`` of :meth:`app.jobs.JobManager.submit` that refuses a training beyond ``limit`` sets.

    Inside the transaction that adds the training job, the stored pattern sets plus the unfinished jobs that
    will store one (this new job among them) are counted; beyond ``limit`` (``BACKLASH_MAX_PATTERN_SETS``) a
    :class:`StorageFullError` (507) rolls the transaction back, so nothing is queued. Counting in the same write
    transaction makes two concurrent requests unable to pass the bound together.
    """
    unfinished = ", ".join(f"'{s.value}'" for s in sorted(UNFINISHED))

    def check(conn: sqlite3.Connection, job: Job) -> None:
        stored = int(conn.execute("SELECT count(*) FROM pattern_sets").fetchone()[0])
        training = int(
            conn.execute(
                f"SELECT count(*) FROM jobs WHERE state IN ({unfinished}) "
                "AND json_extract(meta, '$.pattern_set_id') IS NOT NULL"
            ).fetchone()[0]
        )
        if stored + training > limit:
            raise StorageFullError(
                f"{stored} pattern sets are stored and {training - 1} more are being trained; the service keeps at "
                f"most {limit} (BACKLASH_MAX_PATTERN_SETS): delete unused ones (DELETE /v1/pattern-sets/{{id}}) "
                "or raise the limit",
                cli=f"{stored} pattern sets are stored; the store keeps at most {limit} "
                "(BACKLASH_MAX_PATTERN_SETS): delete unused ones (backlash pattern-sets delete ID) or raise the limit",
            )

    return check
