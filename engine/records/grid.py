"""The sample grid of a record: its interval, its length and where the event sits.

MODEL.md section 2 defines one grid (2048 samples of 0.1 ms, the event at
sample 48); a bench records at its own rate, for its own length. A
:class:`SampleGrid` describes any of them, and :meth:`SampleGrid.window` the
part of it that the test needs (the *test window*: ``PRE_EVENT_TIME`` before the
event to ``POST_EVENT_TIME`` after it, :mod:`engine.constants`). The simulator
renders records on any grid (:func:`engine.simulation.simulate_batch`'s
``grid``), so a measured record is compared with simulations sampled at its own
instants.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from engine.constants import (
    EVENT_INDEX,
    MAX_SAMPLE_INTERVAL,
    MIN_SAMPLE_INTERVAL,
    N_SAMPLES,
    POST_EVENT_TIME,
    PRE_EVENT_TIME,
    SAMPLE_INTERVAL,
)

__all__ = ["PROTOCOL_GRID", "GridError", "SampleGrid", "samples_for"]

#: Relative slack when a time span is converted to a sample count (a decimal interval such as
#: 0.3 ms is not exact in binary: 4.8 ms / 0.3 ms must count as 16 samples, not 17).
_SLACK = 1e-9


class GridError(ValueError):
    """Raised for a sample grid that cannot hold a backlash test; the message says what is missing."""


def samples_for(span: float, sample_interval: float) -> int:
    """Smallest number of samples of ``sample_interval`` [s] that cover ``span`` [s]."""
    return max(0, math.ceil(span / sample_interval - _SLACK))


@dataclass(frozen=True)
class SampleGrid:
    """Sample instants of a record: ``t_k = (k - event_index) * sample_interval`` relative to the event.

    Parameters
    ----------
    sample_interval : float
        Ts [s], in [``MIN_SAMPLE_INTERVAL``, ``MAX_SAMPLE_INTERVAL``] (10 us to 1 ms).
    n_samples : int
        Samples per channel.
    event_index : int
        Index of the sample at the event t_e (the first sample at or after it when the
        event was located between two samples).
    """

    sample_interval: float = SAMPLE_INTERVAL
    n_samples: int = N_SAMPLES
    event_index: int = EVENT_INDEX

    def __post_init__(self) -> None:
        ts = float(self.sample_interval)
        if not (math.isfinite(ts) and ts > 0):
            raise GridError(f"sample_interval must be a positive number of seconds, got {self.sample_interval}")
        if not (MIN_SAMPLE_INTERVAL * (1 - _SLACK) <= ts <= MAX_SAMPLE_INTERVAL * (1 + _SLACK)):
            raise GridError(
                f"sample_interval {ts:g} s is outside the accepted range {MIN_SAMPLE_INTERVAL:g} to "
                f"{MAX_SAMPLE_INTERVAL:g} s (100 kHz to 1 kHz); resample the record into that range"
            )
        object.__setattr__(self, "sample_interval", ts)
        if int(self.n_samples) != self.n_samples or self.n_samples < 2:
            raise GridError(f"a record needs at least 2 samples per channel, got {self.n_samples}")
        object.__setattr__(self, "n_samples", int(self.n_samples))
        if int(self.event_index) != self.event_index or not (0 <= self.event_index < self.n_samples):
            raise GridError(f"event_index must lie in [0, {self.n_samples - 1}], got {self.event_index}")
        object.__setattr__(self, "event_index", int(self.event_index))

    @classmethod
    def protocol(cls, sample_interval: float = SAMPLE_INTERVAL) -> SampleGrid:
        """The shortest grid of interval ``sample_interval`` [s] that covers the test window.

        At 0.1 ms this is MODEL.md's grid (2048 samples, the event at 48).
        """
        before = samples_for(PRE_EVENT_TIME, sample_interval)
        after = samples_for(POST_EVENT_TIME, sample_interval)
        return cls(sample_interval, before + after, before)

    @classmethod
    def around_event(cls, sample_interval: float, before: float, after: float) -> SampleGrid:
        """A grid covering ``before`` [s] before the event and ``after`` [s] from it on."""
        n_before = samples_for(before, sample_interval)
        return cls(sample_interval, n_before + samples_for(after, sample_interval), n_before)

    @property
    def time(self) -> np.ndarray:
        """Sample times relative to the event, t - t_e [s]."""
        return (np.arange(self.n_samples) - self.event_index) * self.sample_interval

    @property
    def covered(self) -> tuple[float, float]:
        """Time covered before the event and from it on [s] (each sample covers [t_k, t_k + Ts))."""
        return self.event_index * self.sample_interval, (self.n_samples - self.event_index) * self.sample_interval

    def missing(self) -> tuple[float, float]:
        """Time missing before and after the event to cover the test window [s] (0 when covered)."""
        before, after = self.covered
        ts = self.sample_interval
        miss_before = PRE_EVENT_TIME - before if before < PRE_EVENT_TIME - _SLACK * ts else 0.0
        miss_after = POST_EVENT_TIME - after if after < POST_EVENT_TIME - _SLACK * ts else 0.0
        return miss_before, miss_after

    def require_test_window(self) -> None:
        """Raise :class:`GridError` unless the grid covers the test window; the message says how much is missing."""
        miss_before, miss_after = self.missing()
        if miss_before or miss_after:
            before, after = self.covered
            parts = []
            if miss_before:
                parts.append(f"{miss_before * 1e3:.4g} ms before the event")
            if miss_after:
                parts.append(f"{miss_after * 1e3:.4g} ms after it")
            raise GridError(
                f"the record covers {before * 1e3:.4g} ms before the event and {after * 1e3:.4g} ms from it on "
                f"({self.n_samples} samples of {self.sample_interval:g} s, event at sample {self.event_index}); "
                f"the backlash test needs at least {PRE_EVENT_TIME * 1e3:.4g} ms before and "
                f"{POST_EVENT_TIME * 1e3:.4g} ms after: {' and '.join(parts)} missing"
            )

    def window(self) -> slice:
        """The samples of the test window (:meth:`protocol` of this interval) within this grid."""
        self.require_test_window()
        w = SampleGrid.protocol(self.sample_interval)
        first = self.event_index - w.event_index
        return slice(first, first + w.n_samples)

    def is_protocol(self) -> bool:
        """Whether this is exactly MODEL.md's grid."""
        return self == PROTOCOL_GRID or (
            math.isclose(self.sample_interval, SAMPLE_INTERVAL, rel_tol=1e-9)
            and self.n_samples == N_SAMPLES
            and self.event_index == EVENT_INDEX
        )


#: MODEL.md section 2's grid: 2048 samples of 0.1 ms, the event at sample 48.
PROTOCOL_GRID = SampleGrid(SAMPLE_INTERVAL, N_SAMPLES, EVENT_INDEX)
