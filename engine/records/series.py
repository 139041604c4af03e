"""A series that need not be held whole: its length, any stretch of it, and its pieces.

What reads a whole record (the event locator, :mod:`engine.records.event`) reads it through
:class:`Series`, one piece of at most :data:`PIECE` samples at a time: an array held in memory
(:class:`ArraySeries`) and a column written to a temporary file as a long record was read
(:class:`engine.records.spill.Spill`) are read the same way, so neither needs a temporary array as long
as the record.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Protocol

import numpy as np

__all__ = ["PIECE", "ArraySeries", "Series", "as_series", "pieces"]

#: Samples per piece [-]: 512 kB of float64.
PIECE: int = 1 << 16


class Series(Protocol):
    """A 1-D float64 series read a stretch at a time."""

    @property
    def size(self) -> int:
        """Its number of samples."""
        ...

    def read(self, start: int, stop: int) -> np.ndarray:
        """Samples ``start .. stop - 1`` (clipped to the series) as a float64 array."""
        ...


class ArraySeries:
    """An array held in memory, as a :class:`Series`."""

    def __init__(self, values: np.ndarray) -> None:
        self._values = np.asarray(values, dtype=float)

    @property
    def size(self) -> int:
        return int(self._values.shape[0])

    def read(self, start: int, stop: int) -> np.ndarray:
        return self._values[max(start, 0) : max(stop, 0)]


def as_series(values: np.ndarray | Series) -> Series:
    """``values`` as a :class:`Series` (an array is wrapped, without a copy)."""
    if isinstance(values, np.ndarray | list | tuple):
        return ArraySeries(np.asarray(values, dtype=float))
    return values


def pieces(
    series: Series, start: int = 0, stop: int | None = None, *, overlap: int = 0, piece: int = PIECE
) -> Iterator[tuple[int, np.ndarray]]:
    """The stretch ``start .. stop - 1`` of ``series`` in pieces: ``(first, samples)`` pairs.

    Parameters
    ----------
    series : Series
    start, stop : int
        The stretch (default: the whole series).
    overlap : int
        Samples each piece reaches past its ``piece`` samples (for differences and look-ahead; clipped at
        ``stop``): consecutive pieces then share ``overlap`` samples.
    piece : int
        Samples per piece, overlap not counted.

    Yields
    ------
    first : int
        Index of the piece's first sample in the series.
    samples : ndarray
        ``series[first : min(first + piece + overlap, stop)]``.
    """
    end = series.size if stop is None else min(stop, series.size)
    for first in range(max(start, 0), end, piece):
        yield first, series.read(first, min(first + piece + overlap, end))
