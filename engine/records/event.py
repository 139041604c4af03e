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
absolute deviation, robust to the signal's impacts). Either way the event lies
between the sample before the located one and the located one, so the time is
known to within one sample: the reported uncertainty is that of a uniform
distribution over the interval, ``Ts / sqrt(12)``; the gap diagnosis fits the
exact instant within the interval (:mod:`engine.diagnosis.space`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from engine.records.errors import ProtocolError

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


def _noise(x: np.ndarray) -> float:
    """White-noise standard deviation from second differences (MAD; 0 for a noiseless record)."""
    d2 = np.diff(x, 2)
    return float(np.median(np.abs(d2)) / _MAD_NORMAL / math.sqrt(6.0)) if d2.size else 0.0


def _from_m_el(x: np.ndarray, tail: int) -> int | None:
    sigma = _noise(x)
    dev = np.abs(x - float(np.median(x[-tail:])))
    thr = max(6.0 * sigma, 0.02 * float(np.max(dev)))
    above = np.flatnonzero(dev > thr)
    if above.size == 0 or above[-1] + 1 >= x.size:
        return None
    return int(above[-1] + 1)


def _from_a1(x: np.ndarray, quiet: int) -> int | None:
    sigma = _noise(x)
    d = np.abs(np.diff(x))
    if d.size == 0:
        return None
    thr = max(8.0 * sigma, 0.05 * float(np.max(d)))
    for k in np.flatnonzero(d > thr) + 1:  # x[k] ends the jump
        stretch = x[k : k + quiet]
        if stretch.size < quiet:
            break
        if np.max(np.abs(stretch - stretch.mean())) <= 4.0 * sigma + 0.1 * d[k - 1]:
            return int(k)
    return None


def locate_event(channels: Mapping[str, np.ndarray], sample_interval: float) -> EventLocation:
    """Locate the event in a record's channels (model units; see the module notes).

    Parameters
    ----------
    channels : mapping of str to ndarray
        The record's channels, one common length.
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
        x = np.asarray(channels[name], dtype=float)
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
