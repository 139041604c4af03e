"""The pattern-set data model: :class:`PatternSet` (metadata plus arrays) and :class:`PatternSetSummary`.

A *pattern set* is what training an identifier produces: a little metadata
(identifier kind, channel, apparent-viscosity group ``c`` [pu], the J1 grid
[kg m^2] it was trained on, the wavelet, hyper-parameters, the reference-model
version) plus a few named numpy arrays (the patterns, the zone widths, scaler
constants, ...). :class:`~engine.storage.PatternStore` keeps them.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from engine.constants import MODEL_VERSION

__all__ = ["PatternSet", "PatternSetSummary", "arrays_equal"]


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
        return self.summary_fields() == other.summary_fields() and arrays_equal(self.arrays, other.arrays)

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


def arrays_equal(a: Mapping[str, np.ndarray], b: Mapping[str, np.ndarray]) -> bool:
    """Whether two named-array mappings hold the same names with bit-identical arrays.

    Parameters
    ----------
    a, b : mapping of str to ndarray

    Returns
    -------
    bool
        True if both hold the same names and every array has equal dtype, shape and bytes.
    """
    if set(a) != set(b):
        return False
    for name in a:
        x, y = np.asarray(a[name]), np.asarray(b[name])
        if x.dtype != y.dtype or x.shape != y.shape or x.tobytes() != y.tobytes():
            return False
    return True
