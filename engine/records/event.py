"""Locating the event t_e in a record that does not say where it is.

At the event the motor is switched off (MODEL.md section 2): its torque m_el
drops to zero and stays there, and the motor-side acceleration a1 (which is
``r Omega_b (m_el - m_c - m_f) / T1``) jumps to the value it keeps while the
clutch crosses the backlash zone (zero without friction) for at least the
first millisecond. Both are sharp in every sampled record, whatever the
interval; a2 and v2 are smooth at t_e and omega1 only bends, so a record with
none of m_el and a1 needs its ``event_index``.

* **m_el** (preferred): the event is the first sample after the last one that
  departs from the post-event level (the median of the record's last 100 ms,
  which always follow the event; zero unless the sensor has an offset) by more
  than ``max(6 sigma, 2 % of the record's largest departure)``.
* **a1**: the event is the first sample that ends a jump (a first difference
  beyond ``max(8 sigma, 5 % of the largest one)``) and starts a quiet stretch
  of 1 ms (every sample within ``4 sigma + 10 %`` of the jump of the stretch's mean).

sigma is the channel's white-noise level from its second differences (median
absolute deviation, robust to the signal's impacts; over the whole record, read
in pieces of :data:`~engine.records.series.PIECE` samples when it is longer). Either way the event lies
between the sample before the located one and the located one, so the time is
known to within one sample: the reported uncertainty is that of a uniform
distribution over the interval, ``Ts / sqrt(12)``; the gap diagnosis fits the
exact instant within the interval (:mod:`engine.diagnosis.space`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from engine.records.errors import ProtocolError
from engine.records.order import median
from engine.records.series import PIECE, Series, as_series, pieces

__all__ = ["LOCATING_CHANNELS", "EventLocation", "locate_event"]

#: Channels the event can be located from, in the order they are tried.
LOCATING_CHANNELS: tuple[str, ...] = ("m_el", "a1")
#: Length of the quiet stretch that follows the event in a1 [s].
QUIET_TIME: float = 1e-3
#: Stretch at the end of a record whose median is m_el's post-event level [s] (records cover 200 ms after the event).
LEVEL_TIME: float = 0.1
#: Median absolute deviation of a unit normal.
_MAD_NORMAL = 0.6744897501960817


@dataclass(frozen=True)
class EventLocation:
    """Where the event was located in a record.

    Attributes
    ----------
    index : int
        The first sample at or after the event.
    interval : tuple of float
        The event lies in ``(interval[0], interval[1]]`` relative to sample ``index`` [s]
        (``(-Ts, 0]``).
    sigma : float
        Standard uncertainty of the event time [s] (uniform over the interval: Ts / sqrt(12)).
    channel : str
        The channel it was located from.
    method : str
        How, in words.
    """

    index: int
    interval: tuple[float, float]
    sigma: float
    channel: str
    method: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "index": self.index,
            "interval": list(self.interval),
            "sigma": self.sigma,
            "channel": self.channel,
            "method": self.method,
        }


def _noise(x: Series) -> float:
    """White-noise standard deviation from second differences (MAD; 0 for a noiseless record)."""
    if x.size < 3:
        return 0.0
    if x.size <= PIECE:  # held in one piece: numpy's median
        return float(np.median(np.abs(np.diff(x.read(0, x.size), 2))) / _MAD_NORMAL / math.sqrt(6.0))

    def second_differences() -> Iterator[np.ndarray]:
        return (np.abs(np.diff(piece, 2)) for _, piece in pieces(x, overlap=2))

    return float(median(second_differences, x.size - 2) / _MAD_NORMAL / math.sqrt(6.0))


def _from_m_el(x: Series, tail: int) -> int | None:
    sigma = _noise(x)
    level = float(np.median(x.read(x.size - tail, x.size)))
    largest = max(float(np.max(np.abs(piece - level))) for _, piece in pieces(x))
    thr = max(6.0 * sigma, 0.02 * largest)
    last = None  # the last sample beyond the threshold: pieces from the end
    for first in range((x.size - 1) // PIECE * PIECE, -1, -PIECE):
        above = np.flatnonzero(np.abs(x.read(first, first + PIECE) - level) > thr)
        if above.size:
            last = first + int(above[-1])
            break
    if last is None or last + 1 >= x.size:
        return None
    return last + 1


def _from_a1(x: Series, quiet: int) -> int | None:
    sigma = _noise(x)
    if x.size < 2:
        return None
    jumps = [float(np.max(np.abs(np.diff(piece)))) for _, piece in pieces(x, overlap=1) if piece.size > 1]
    thr = max(8.0 * sigma, 0.05 * max(jumps))
    for first, piece in pieces(x, overlap=quiet):  # x[first + j + 1] ends the jump d[first + j]
        d = np.abs(np.diff(piece[: PIECE + 1]))
        for j in np.flatnonzero(d > thr):
            stretch = piece[j + 1 : j + 1 + quiet]
            if stretch.size < quiet:
                return None
            if np.max(np.abs(stretch - stretch.mean())) <= 4.0 * sigma + 0.1 * d[j]:
                return first + int(j) + 1
    return None


def locate_event(channels: Mapping[str, np.ndarray | Series], sample_interval: float) -> EventLocation:
    """Locate the event in a record's channels (model units; see the module notes).

    Parameters
    ----------
    channels : mapping of str to ndarray or Series
        The record's channels, one common length: arrays, or series read in pieces (the columns of a
        long record on disk, :mod:`engine.records.streamed`). Either way they are read
        :data:`~engine.records.series.PIECE` samples at a time (no temporary array is longer), and the
        answer is the same: the median of the second differences of a longer series is selected
        exactly (:func:`engine.records.order.median`).
    sample_interval : float
        Ts [s].

    Returns
    -------
    EventLocation

    Raises
    ------
    ProtocolError
        The record holds neither m_el nor a1, or neither shows the event's signature;
        the message asks for ``event_index``.
    """
    ts = float(sample_interval)
    quiet = max(3, math.ceil(QUIET_TIME / ts - 1e-9))
    tried = []
    for name in LOCATING_CHANNELS:
        if name not in channels:
            continue
        x = as_series(channels[name])
        if name == "m_el":
            k = _from_m_el(x, max(3, min(x.size // 2, math.ceil(LEVEL_TIME / ts - 1e-9))))
            how = (
                "m_el drops to its post-event level (first sample after the last one beyond 2 % of its largest "
                "departure from that level or 6 noise sigma)"
            )
        else:
            k = _from_a1(x, quiet)
            how = "a1 jumps and then stays quiet for 1 ms (the motor torque switched off)"
        if k is not None and k > 0:
            return EventLocation(k, (-ts, 0.0), ts / math.sqrt(12.0), name, how)
        tried.append(name)
    if tried:
        raise ProtocolError(
            f"the event could not be located from {' or '.join(tried)}: no switch-off of the motor torque "
            f"is visible; give event_index (the sample at the event)"
        )
    raise ProtocolError(
        f"the record gives no event_index and holds neither m_el nor a1, from which the event could be located "
        f"(it holds {', '.join(channels)}); give event_index (the sample at the event)"
    )
