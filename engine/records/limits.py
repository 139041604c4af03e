"""The largest magnitude a sample of a record may have: one limit for every plant's record boundary.

A record whose values are absurdly large does not fail loudly further on: squares and sums of
them overflow to inf, a noise estimate of inf makes every residual zero, and the answer comes out
confident (issue 50: every value x 1e200 gave ``no_gap`` at confidence 1.0). Such a record is
refused where it is read, by :func:`require_magnitude`, with a message naming the series, the
sample and what to check. The drive's :class:`~engine.records.record.Record`, the EMPS reader
(:mod:`engine.plants.emps.record`) and the BRFD reader (:mod:`engine.plants.brfd.record`) all
call it, on their values in the engine's units (SI, per unit for the drive's torque).
"""

from __future__ import annotations

from typing import Final

import numpy as np

from engine.records.errors import RecordError

__all__ = ["MAX_ABS_SAMPLE", "MAX_SAMPLES", "first_beyond", "magnitude_error", "require_length", "require_magnitude"]

#: Largest accepted magnitude of a sample, in the engine's unit of its series (m/s^2, rad/s, m/s,
#: pu, m, N, V, s). Physically motivated: no sensor of these plants reads anywhere near it (the
#: drive's largest channel over its plausible box is about 150 m/s^2; a channel in a wrong unit,
#: mm/s or deg/s, reaches 1e3-1e4; even raw counts of a 32-bit converter stay below 2.2e9, and
#: such records are accepted and then get a ``channel_scale`` warning rather than a refusal),
#: while every computation keeps a margin of more than 200 decades: the square is 1e24, a sum of
#: squares over a record of 1e7 samples 1e31, a fourth power 1e48 (float64 overflows at 1.8e308).
#: A limit like 1e150 would not do: its square summed over 2048 samples already overflows.
MAX_ABS_SAMPLE: Final[float] = 1e12


#: Most samples per series of a record held whole. A diagnosis reads only the test window (about 205 ms:
#: 20 500 samples at the finest accepted interval of 10 us), so no answer needs more; the cap keeps a
#: record's memory, its answer and what is stored of it bounded (issue 51: a 10^7-sample record
#: became a 4.6 GB worker). 10^6 samples is 10 s at 10 us: cut a longer record around the event.
#: A record read in pieces (a CSV: :mod:`engine.records.streamed`) is not held whole and not capped
#: (issue 54): only its excerpt around the event is kept, and the service's bodies are bounded by
#: ``BACKLASH_MAX_BODY_BYTES``.
MAX_SAMPLES: Final[int] = 1_000_000


def require_length(n: int, what: str) -> None:
    """Refuse a series of more than :data:`MAX_SAMPLES` samples.

    Parameters
    ----------
    n : int
        Its number of samples.
    what : str
        How the message names the record or series, e.g. ``"channel 'a1'"``.

    Raises
    ------
    RecordError
        Naming the series, its length, the limit and what to do.
    """
    if n > MAX_SAMPLES:
        raise RecordError(
            f"{what} has {n} samples, more than the {MAX_SAMPLES} a record may hold; send the stretch the analysis "
            "needs (the backlash drive's diagnosis reads only its test window, 4.8 ms before to 200 ms after the "
            "event; a plant of whole records, a shorter record or a coarser sample interval)"
        )


def require_magnitude(values: np.ndarray, what: str, unit: str) -> None:
    """Refuse a series holding a sample larger in magnitude than :data:`MAX_ABS_SAMPLE`.

    Parameters
    ----------
    values : ndarray
        The samples, finite (check that first), in the engine's unit ``unit``.
    what : str
        How the message names the series, e.g. ``"channel 'omega1'"`` or ``"run1: qm"``.
    unit : str
        The unit of ``values`` as the message should name it.

    Raises
    ------
    RecordError
        Naming the series, the first offending sample (0-based), its value and what to check.
    """
    i = first_beyond(values)
    if i is not None:
        raise magnitude_error(what, unit, i, float(np.asarray(values, dtype=float)[i]))


def first_beyond(values: np.ndarray) -> int | None:
    """Index of the first sample of ``values`` (finite) beyond +-:data:`MAX_ABS_SAMPLE`, or None (no float
    temporary as long as ``values``: two boolean masks)."""
    x = np.asarray(values, dtype=float)
    too_large = (x > MAX_ABS_SAMPLE) | (x < -MAX_ABS_SAMPLE)
    return int(np.flatnonzero(too_large)[0]) if np.any(too_large) else None


def magnitude_error(what: str, unit: str, index: int, value: float) -> RecordError:
    """The refusal of :func:`require_magnitude`: sample ``index`` of the series ``what`` holds ``value`` [``unit``]."""
    return RecordError(
        f"{what} holds {value:.3g} {unit} at sample {index}: beyond +-{MAX_ABS_SAMPLE:.0e} {unit}, far more than any "
        "sensor of the plant reads, and too large to compute with; check the record's units and scaling "
        "(a wrong exponent, raw counts, a misplaced decimal point)"
    )
