"""Validation of a pattern set before it is saved: every field checked, then encoded into a row.

:func:`prepare` turns a :class:`~engine.storage.PatternSet` into a :class:`Prepared` row or
raises :class:`~engine.storage.InvalidPatternSet` saying what to fix; nothing is written
before it succeeds.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from engine.constants import CHANNELS
from engine.storage.codec import array_metadata, encode_arrays, sha256, validate_arrays
from engine.storage.errors import InvalidPatternSet
from engine.storage.models import PatternSet

__all__ = ["Prepared", "prepare", "require_c", "require_channel", "require_text", "to_json"]

_ID_RE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")


def require_channel(channel: object) -> str:
    """``channel`` if it is one of :data:`engine.constants.CHANNELS`; else :class:`InvalidPatternSet`."""
    if not isinstance(channel, str) or channel not in CHANNELS:
        raise InvalidPatternSet(f"unknown channel {channel!r}; use one of: {', '.join(CHANNELS)}")
    return channel


def require_c(c: object, what: str = "c") -> float:
    """``c`` [pu] as a float if it is a finite real number; else :class:`InvalidPatternSet`."""
    if isinstance(c, bool) or not isinstance(c, (int, float, np.integer, np.floating)):
        raise InvalidPatternSet(f"{what} must be a real number [pu], got {type(c).__name__}")
    value = float(c)
    if not math.isfinite(value):
        raise InvalidPatternSet(f"{what} must be finite [pu], got {value!r}")
    return value


def require_text(value: object, name: str) -> str:
    """``value`` if it is a non-empty string; else :class:`InvalidPatternSet` naming ``name``."""
    if not isinstance(value, str) or not value.strip():
        raise InvalidPatternSet(f"{name} must be a non-empty string, got {value!r}")
    return value


def to_json(value: object, name: str) -> tuple[str, Any]:
    """Serialise ``value`` to canonical JSON; return the text and its parsed (normalised) form."""
    try:
        text = json.dumps(value, sort_keys=True, allow_nan=False, separators=(",", ":"))
    except (TypeError, ValueError) as exc:
        raise InvalidPatternSet(
            f"{name} must be JSON-serialisable (str keys; str, int, float, bool, None, list, dict values; "
            f"finite floats; convert numpy scalars/arrays with .item()/.tolist()): {exc}"
        ) from exc
    return text, json.loads(text)


@dataclass(frozen=True)
class Prepared:
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


def prepare(ps: PatternSet) -> Prepared:
    """Validate ``ps`` and encode it into a row ready to insert.

    Parameters
    ----------
    ps : PatternSet
        The set to save (its ``id`` may be ``None``; ``created_at`` is ignored).

    Returns
    -------
    Prepared

    Raises
    ------
    InvalidPatternSet
        For the first malformed field; the message says what to fix.
    """
    if not isinstance(ps, PatternSet):
        raise InvalidPatternSet(f"save() takes a PatternSet, got {type(ps).__name__}")
    if ps.id is not None and (not isinstance(ps.id, str) or not _ID_RE.match(ps.id)):
        raise InvalidPatternSet(
            f"id {ps.id!r} is not allowed; leave it None (the store assigns a uuid4 hex) "
            "or use 1-64 characters from [A-Za-z0-9_-]"
        )
    kind = require_text(ps.kind, "kind")
    channel = require_channel(ps.channel)
    c = require_c(ps.c)
    wavelet = require_text(ps.wavelet, "wavelet")
    model_version = require_text(ps.model_version, "model_version")

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
    params_text, params = to_json(dict(ps.params), "params")
    j1_text, _ = to_json(j1, "j1_values")

    arrays = validate_arrays(ps.arrays)
    meta = array_metadata(arrays)
    meta_text, _ = to_json(meta, "arrays metadata")
    blob = encode_arrays(arrays)
    return Prepared(
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
        sha256=sha256(blob),
        blob=blob,
    )
