"""A record's time column: the sample interval its steps define, checked as it is read, in one piece or many.

A time column ``t`` [s] defines the interval as its mean step, ``(t[-1] - t[0]) / (n - 1)``, and must
be finite, increasing and uniform: every step within :data:`TIME_TOLERANCE` of the mean, relative to
it (else the record would be misread as uniformly sampled). :class:`TimeSteps` takes the column a
piece at a time and keeps only what the checks need (its ends, its smallest and largest steps, the first
faults), so a long record's column is never held whole; the largest deviation from the mean step is
that of the smallest or the largest step, since rounding keeps ``|step - mean|`` monotonic on either
side. Only a column that fails the uniformity check is read once more (:meth:`TimeSteps.interval`'s
``again``), to name its first worst step as the one-piece reading does (:func:`numpy.argmax`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable

import numpy as np

from engine.records.errors import RecordError

__all__ = ["TIME_TOLERANCE", "TimeSteps", "sample_interval_of"]

#: Largest deviation of a time column's steps from their mean, relative to the step, that still
#: counts as a uniform grid (a time column printed with 6 significant digits passes).
TIME_TOLERANCE: float = 1e-3


class TimeSteps:
    """The checks of a time column read in pieces (:meth:`add` each, in order; then :meth:`interval`)."""

    def __init__(self) -> None:
        self.size = 0
        self._first = 0.0
        self._last = 0.0
        self._non_finite: int | None = None  # index of the first non-finite value
        self._not_increasing: int | None = None  # index of the first sample not after its predecessor
        self._smallest = (np.inf, -1)  # the smallest step and the index of the sample it leads to (first such)
        self._largest = (-np.inf, -1)

    def add(self, piece: np.ndarray) -> None:
        """Take the column's next values (1-D, float)."""
        piece = np.asarray(piece, dtype=float)
        if piece.size == 0:
            return
        offset = self.size
        bad = ~np.isfinite(piece)
        if self._non_finite is None and bad.any():
            self._non_finite = offset + int(np.flatnonzero(bad)[0])
        steps = np.diff(piece) if offset == 0 else np.diff(np.concatenate(([self._last], piece)))
        first_step = offset if offset else 1  # the sample the first of ``steps`` leads to
        if self._non_finite is None and steps.size:
            not_up = np.flatnonzero(steps <= 0)
            if self._not_increasing is None and not_up.size:
                self._not_increasing = first_step + int(not_up[0])
            low, high = int(np.argmin(steps)), int(np.argmax(steps))
            if steps[low] < self._smallest[0]:
                self._smallest = (float(steps[low]), first_step + low)
            if steps[high] > self._largest[0]:
                self._largest = (float(steps[high]), first_step + high)
        if offset == 0:
            self._first = float(piece[0])
        self._last = float(piece[-1])
        self.size += piece.size

    def interval(self, again: Callable[[], Iterable[np.ndarray]] | None = None) -> float:
        """The sample interval [s] the column defines.

        Parameters
        ----------
        again : callable, optional
            Returns the column's pieces once more; needed only to name the first worst step of a column
            that is not uniform (without it, the first of the smallest and the largest step that deviates
            most is named).

        Raises
        ------
        RecordError
            Fewer than two values, a non-finite value, time not increasing, or steps that differ by more
            than ``TIME_TOLERANCE`` of the mean step (resample the record first).
        """
        if self.size < 2:
            raise RecordError(f"the time column 't' needs at least 2 values, got shape ({self.size},)")
        if self._non_finite is not None:
            raise RecordError(f"the time column 't' holds a non-finite value at sample {self._non_finite}")
        ts = float((np.float64(self._last) - np.float64(self._first)) / (self.size - 1))
        if not ts > 0 or self._not_increasing is not None:
            bad = self._not_increasing if self._not_increasing is not None else 1
            raise RecordError(f"the time column 't' must increase from sample to sample; it does not at sample {bad}")
        deviations = [(abs(step - ts) / ts, index, step) for step, index in (self._smallest, self._largest)]
        worst = max(d for d, _, _ in deviations)
        if worst > TIME_TOLERANCE:
            bad, step = min((index, step) for d, index, step in deviations if d == worst)
            if again is not None:
                bad, step = self._first_worst(again, ts, worst)
            raise RecordError(
                f"the time column 't' is not uniform: the step to sample {bad} is {step:.6g} s against a mean "
                f"of {ts:.6g} s; resample the record onto a uniform grid first"
            )
        return ts

    @staticmethod
    def _first_worst(pieces: Callable[[], Iterable[np.ndarray]], ts: float, worst: float) -> tuple[int, float]:
        """The first step whose deviation is ``worst`` (the index of the sample it leads to, and the step)."""
        offset = 0
        last: float | None = None
        for piece in pieces():
            piece = np.asarray(piece, dtype=float)
            steps = np.diff(piece) if last is None else np.diff(np.concatenate(([last], piece)))
            hits = np.flatnonzero(np.abs(steps - ts) / ts == worst)
            if hits.size:
                first_step = offset if last is not None else 1
                return first_step + int(hits[0]), float(steps[hits[0]])
            offset += piece.size
            last = float(piece[-1]) if piece.size else last
        raise AssertionError("the worst step of the time column was not found again")


def sample_interval_of(from_time: float | None, given: float | None, default: float) -> float:
    """The record's sample interval [s] from its time column's and the one given, checked.

    Parameters
    ----------
    from_time : float or None
        The interval the time column defines [s] (:meth:`TimeSteps.interval`); None without a column.
    given : float or None
        The ``sample_interval`` the record gave [s], if any.
    default : float
        The interval of a record that gives neither [s].

    Raises
    ------
    RecordError
        The two contradict each other (beyond :data:`TIME_TOLERANCE`), or the interval is not a
        positive finite number.
    """
    if from_time is not None:
        if given is not None and not math.isclose(float(given), from_time, rel_tol=TIME_TOLERANCE):
            raise RecordError(
                f"sample_interval {float(given):g} s contradicts the time column 't' (step {from_time:.6g} s); "
                f"give one of them"
            )
        ts = from_time
    else:
        ts = default if given is None else float(given)
    if not (math.isfinite(ts) and ts > 0):
        raise RecordError(f"sample_interval must be a positive number of seconds, got {ts}")
    return ts
