"""The exact median of a series read in pieces, in memory bounded by a piece (not by the series).

The event locator's noise level is a median over the whole record (:mod:`engine.records.event`); a
record too long to hold is read in pieces (:mod:`engine.records.pieces`), so the median is selected
by radix: every float64 is mapped to a 64-bit key whose unsigned order is the values' order, and the
key of the ``k``-th smallest value is found 16 bits at a time from a histogram of the candidates'
next 16 bits (four passes over the pieces, 65 536 counts each). One more pass finds the value just
above it for an even count. The result is the very number :func:`numpy.median` gives (the middle
value, or the mean of the two middle values computed as ``(a + b) / 2``), so a record gives the same
answer whether it was held whole or read in pieces.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np

__all__ = ["median", "order_statistic"]

#: Bits of the key resolved per pass over the pieces.
_DIGIT_BITS = 16
_DIGIT_MASK = np.uint64((1 << _DIGIT_BITS) - 1)
_SIGN = np.uint64(1 << 63)
_SHIFTS = (48, 32, 16, 0)

#: The pieces of a series, read again on every call (each a 1-D float64 array; together the series).
Pieces = Callable[[], Iterable[np.ndarray]]


def _keys(x: np.ndarray) -> np.ndarray:
    """Unsigned 64-bit keys in the order of the float64 values ``x`` (no NaN): the sign bit flipped for
    positive values, every bit for negative ones."""
    bits = np.ascontiguousarray(x, dtype=np.float64).view(np.uint64)
    return np.where(bits & _SIGN, ~bits, bits | _SIGN)


def _value(key: int) -> float:
    """The float64 whose key (:func:`_keys`) is ``key``."""
    k = np.uint64(key)
    bits = k ^ _SIGN if k & _SIGN else ~k
    return float(np.array([bits], dtype=np.uint64).view(np.float64)[0])


def _key(pieces: Pieces, k: int) -> int:
    """The key of the ``k``-th smallest value (0-based) of the series."""
    prefix = 0
    known = 0  # mask of the key's bits resolved so far
    for shift in _SHIFTS:
        counts = np.zeros(1 << _DIGIT_BITS, dtype=np.int64)
        for piece in pieces():
            keys = _keys(piece)
            if known:
                keys = keys[(keys & np.uint64(known)) == np.uint64(prefix)]
            digits = ((keys >> np.uint64(shift)) & _DIGIT_MASK).astype(np.intp)
            counts += np.bincount(digits, minlength=1 << _DIGIT_BITS)
        cumulative = np.cumsum(counts)
        digit = int(np.searchsorted(cumulative, k, side="right"))
        if digit >= cumulative.size:
            raise ValueError(f"order statistic {k} of a series of {int(cumulative[-1])} values")
        k -= int(cumulative[digit - 1]) if digit else 0
        prefix |= digit << shift
        known |= int(_DIGIT_MASK) << shift
    return prefix


def order_statistic(pieces: Pieces, k: int) -> float:
    """The ``k``-th smallest value (0-based) of the series that ``pieces`` reads (no NaN), exactly.

    Parameters
    ----------
    pieces : callable
        Returns an iterable of 1-D float arrays that together are the series; called once per pass (five).
    k : int
        0 for the smallest value.

    Returns
    -------
    float

    Raises
    ------
    ValueError
        The series holds fewer than ``k + 1`` values.
    """
    return _value(_key(pieces, k))


def median(pieces: Pieces, n: int) -> float:
    """The median of the ``n`` values (no NaN) that ``pieces`` reads, exactly as :func:`numpy.median` gives it.

    Parameters
    ----------
    pieces : callable
        Returns an iterable of 1-D float arrays that together are the series; called once per pass (four
        for an odd ``n``, five for an even one).
    n : int
        How many values the series holds (at least one).

    Returns
    -------
    float
        The middle value, or for an even ``n`` the two middle values' mean, ``(a + b) / 2``.
    """
    if n < 1:
        raise ValueError("the median of an empty series")
    low_key = _key(pieces, (n - 1) // 2)
    low = _value(low_key)
    if n % 2:
        return low
    at_most = 0  # values whose key is <= low's, and the smallest key above it
    above: int | None = None
    for piece in pieces():
        keys = _keys(piece)
        at_most += int(np.count_nonzero(keys <= np.uint64(low_key)))
        higher = keys[keys > np.uint64(low_key)]
        if higher.size:
            smallest = int(higher.min())
            above = smallest if above is None else min(above, smallest)
    high = low if at_most > n // 2 or above is None else _value(above)
    return float((np.float64(low) + np.float64(high)) / 2.0)
