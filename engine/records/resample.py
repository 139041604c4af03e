"""A record on MODEL.md's grid, for what can only read that grid: stored pattern sets.

Pattern sets are trained on simulations of 2048 samples of 0.1 ms with the
event at sample 48 (and their wavelet features depend on exactly that). A
record of another interval is brought onto that grid by
:func:`scipy.signal.resample_poly`: polyphase filtering with its Kaiser-window
FIR, which is the anti-aliasing low-pass when the record is finer than 0.1 ms
and the band-limited interpolator when it is coarser; ``padtype="line"``
extends the record by its end slopes so the ends do not ring. The ratio of the
intervals is taken as a fraction ``up / down`` (denominators up to 10 000, at
most 1 us of drift over the test window), and the record is aligned so that an
output sample falls on the event. Where the record stops short of the target's
last instant (by less than one of its own samples, e.g. 199 ms at 1 ms against
199.9 ms), an odd reflection about its last sample (which continues its slope)
supplies the rest.

The gap diagnosis does not resample: it simulates on the record's own grid.
"""

from __future__ import annotations

import logging
import math
from fractions import Fraction

import numpy as np

from engine.constants import POST_EVENT_TIME, PRE_EVENT_TIME
from engine.records.errors import ProtocolError
from engine.records.grid import PROTOCOL_GRID, SampleGrid
from engine.records.record import Record

logger = logging.getLogger(__name__)

__all__ = ["MAX_DRIFT", "interval_ratio", "reach", "resample_to_grid", "to_protocol_grid"]

#: Largest drift [s] over the test window that the rational approximation of the interval ratio may cause.
MAX_DRIFT: float = 1e-6


def interval_ratio(source: float, target: float) -> Fraction:
    """``source / target`` as a fraction ``up / down`` whose drift over the test window is below ``MAX_DRIFT``.

    Raises
    ------
    ProtocolError
        No fraction with a denominator up to 10 000 is close enough.
    """
    exact = source / target
    span = PRE_EVENT_TIME + POST_EVENT_TIME
    for limit in (1000, 10_000):
        r = Fraction(exact).limit_denominator(limit)
        if abs(float(r) - exact) / exact * span <= MAX_DRIFT:
            return r
    raise ProtocolError(
        f"sample_interval {source:g} s has no simple ratio to {target:g} s (within {MAX_DRIFT:g} s over the test "
        f"window); resample the record to a rounder interval"
    )


def resample_to_grid(x: np.ndarray, source: SampleGrid, target: SampleGrid) -> np.ndarray:
    """Samples of one channel on ``source`` resampled onto ``target`` (same event instant).

    Parameters
    ----------
    x : ndarray, shape (source.n_samples,)
        The channel.
    source, target : SampleGrid
        Its grid and the wanted one.

    Returns
    -------
    ndarray, shape (target.n_samples,)
    """
    x = np.asarray(x, dtype=float)
    if math.isclose(source.sample_interval, target.sample_interval, rel_tol=1e-12):
        first = source.event_index - target.event_index
        idx = np.clip(np.arange(first, first + target.n_samples), 0, source.n_samples - 1)
        return x[idx]
    r = interval_ratio(source.sample_interval, target.sample_interval)
    up, down = r.numerator, r.denominator
    # left padding so that an output sample lands on the event and the target's first sample is inside
    need_before = target.event_index * target.sample_interval + 8 * source.sample_interval
    lead = max(source.event_index, math.ceil(need_before / source.sample_interval))
    lead += (-lead) % down  # (lead * up / down) output samples from the start to the event: an integer
    pad_left = lead - source.event_index
    # right padding: the target's last sample plus a few source samples
    need_after = (target.n_samples - target.event_index) * target.sample_interval + 8 * source.sample_interval
    tail = max(source.n_samples - source.event_index, math.ceil(need_after / source.sample_interval))
    pad_right = tail - (source.n_samples - source.event_index)
    # odd reflection about the end samples continues the record's slope where the target reaches past it
    xp = np.pad(x, (pad_left, pad_right), mode="reflect", reflect_type="odd")
    from scipy.signal import resample_poly  # here, not at the top: scipy.signal adds 1-2 s to every process start

    y = resample_poly(xp, up, down, padtype="line")
    at_event = lead * up // down
    first = at_event - target.event_index
    return y[first : first + target.n_samples]


def reach(sample_interval: float) -> int:
    """Samples of ``sample_interval`` [s] beyond the test window on either side that :func:`to_protocol_grid`
    reads: the 8 :func:`resample_to_grid` adds, the half-length of :func:`scipy.signal.resample_poly`'s
    filter (``10 max(up, down)`` output samples, ``10 max(1, down / up)`` input samples) and 8 to spare
    (at most 116 samples, at 10 us)."""
    r = interval_ratio(sample_interval, PROTOCOL_GRID.sample_interval)
    return 8 + math.ceil(10 * max(r.numerator, r.denominator) / r.numerator) + 8


def to_protocol_grid(record: Record) -> Record:
    """The record's test window on MODEL.md's grid (2048 x 0.1 ms, event at 48), model units.

    Returns the record's own test window unchanged when it is already on that grid. Otherwise only
    the window and :func:`reach` samples on either side are resampled, not the whole record, in
    memory bounded by the window: the same numbers, since every output sample's filter lies within
    them. But where the record ends less than :func:`reach` samples beyond the window, the filter
    reads the resampler's extension of the record there (``padtype="line"``: a line whose slope runs
    from the record's first sample to its last), so the record's other end is kept too.
    """
    window, _ = record.test_window()
    if window.grid.is_protocol():
        return window
    win, margin = record.grid.window(), reach(record.sample_interval)
    short_before, short_after = win.start < margin, record.n_samples - win.stop < margin
    first = 0 if short_after else max(0, win.start - margin)
    stop = record.n_samples if short_before else min(record.n_samples, win.stop + margin)
    source = SampleGrid(record.sample_interval, stop - first, record.event_index - first)
    channels = {c: resample_to_grid(x[first:stop], source, PROTOCOL_GRID) for c, x in record.channels.items()}
    logger.debug(
        "resampled %d channels from %g s to %g s (scipy.signal.resample_poly)",
        len(channels),
        record.sample_interval,
        PROTOCOL_GRID.sample_interval,
    )
    return Record(
        channels=channels,
        sample_interval=PROTOCOL_GRID.sample_interval,
        event_index=PROTOCOL_GRID.event_index,
        conditions=record.conditions,
        event_time=record.event_time,
    )
