"""The backlash-test record: the data every part of the engine exchanges.

A record holds up to five channels, the same number of samples each, taken
every ``sample_interval`` seconds, with sample ``event_index`` at the event t_e
(MODEL.md section 2 defines one such grid; :mod:`engine.records.grid` any
other). Inside the engine the samples are always in MODEL.md's units;
``units`` remembers the units the record came in, and :meth:`Record.to_dict`
writes them back in those units. Reading a record as a bench gives it (units,
a time column, no event index) is :func:`engine.records.protocol.record_from_data`.

A record may be an *excerpt* of a longer one (:class:`Excerpt`): a record too long to hold is read
in pieces and only the stretch around its event that analyses read is kept
(:mod:`engine.records.streamed`). Its samples, grid and event index are those of the excerpt; what it
reports of itself (:meth:`Record.test_window`'s :class:`WindowUse`, :attr:`Record.origin`) counts
samples in the record as it was read.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from engine.constants import CHANNEL_UNITS, CHANNELS, EVENT_INDEX, SAMPLE_INTERVAL
from engine.records.errors import ProtocolError, RecordError
from engine.records.event import EventLocation
from engine.records.grid import GridError, SampleGrid
from engine.records.limits import require_length, require_magnitude
from engine.records.units import UnitError, factor, from_model_units

__all__ = ["Excerpt", "Record", "WindowUse"]


@dataclass(frozen=True)
class Excerpt:
    """Where a record lies in the record it was cut from (a long record read in pieces).

    Attributes
    ----------
    first : int
        The record's sample 0 is sample ``first`` of the record read.
    n_samples : int
        Samples per channel of the record read.
    """

    first: int
    n_samples: int


@dataclass(frozen=True)
class WindowUse:
    """Which samples of a record an analysis used (the test window, :meth:`SampleGrid.window`).

    Attributes
    ----------
    first, stop : int
        The samples ``first .. stop - 1`` of the record were used.
    n_samples : int
        Samples per channel in the record.
    t_start, t_end : float
        Time span used relative to the event [s] (``t_end`` is the end of the last sample's interval).
    """

    first: int
    stop: int
    n_samples: int
    t_start: float
    t_end: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: the samples used and how many were ignored before and after them."""
        return {
            "first_sample": self.first,
            "stop_sample": self.stop,
            "samples_used": self.stop - self.first,
            "samples_ignored_before": self.first,
            "samples_ignored_after": self.n_samples - self.stop,
            "t_start": round(self.t_start, 12),
            "t_end": round(self.t_end, 12),
        }


@dataclass(frozen=True)
class Record:
    """One backlash-test record.

    Parameters
    ----------
    channels : mapping of str to ndarray
        Non-empty subset of ``CHANNELS`` in MODEL.md's units (a1 [m/s^2], m_el [pu],
        omega1 [rad/s], a2 [m/s^2], v2 [m/s]); 1-D float arrays of one common length, finite and
        at most 1e12 in magnitude (:data:`engine.records.limits.MAX_ABS_SAMPLE`).
    sample_interval : float
        Ts [s], 10 us to 1 ms.
    event_index : int
        Index of the sample at the event t_e (or the first after it, when the event
        was located between samples: see ``event_location``).
    conditions : mapping of str to float
        What is known about the operating point (e.g. ``J1`` [kg m^2], ``c`` [pu],
        ``c1`` [pu], ``K`` [m], ``base_torque`` [N*m]); only what is known.
    event_time : float or None
        t_e [s] since the motor was switched on, when known (simulated records).
    units : mapping of str to str
        Units the record was given in, per channel (a channel not named is in its
        model unit); :meth:`to_dict` writes the samples back in them.
    event_location : EventLocation or None
        How the event was located from the data, when the record did not give ``event_index``
        (its ``index`` counts samples in the record as it was read: :attr:`origin`).
    excerpt : Excerpt or None
        Where the record lies in a longer record it was cut from (:attr:`origin`); None for a
        record as it was read.

    Channels are copied, and the copies made read-only, unless an array is already read-only and
    owns its data (as the arrays :func:`~engine.records.protocol.record_from_data` makes, and every
    record's channels): such an array is kept as it is, so a record read once is not copied again.

    Raises
    ------
    RecordError
        Malformed channels (unknown name, unequal lengths, non-finite values, a value beyond
        +-``MAX_ABS_SAMPLE`` = 1e12 in the model's unit, :mod:`engine.records.limits`).
    ProtocolError
        The grid cannot hold a backlash test: interval outside 10 us - 1 ms, or less
        than 4.8 ms before or 200 ms after the event (the message says how much is missing).
    """

    channels: Mapping[str, np.ndarray]
    sample_interval: float = SAMPLE_INTERVAL
    event_index: int = EVENT_INDEX
    conditions: Mapping[str, float] = field(default_factory=dict)
    event_time: float | None = None
    units: Mapping[str, str] = field(default_factory=dict)
    event_location: EventLocation | None = None
    excerpt: Excerpt | None = None

    def __post_init__(self) -> None:
        if not self.channels:
            raise RecordError("a record needs at least one channel; known channels: " + ", ".join(CHANNELS))
        clean: dict[str, np.ndarray] = {}
        n: int | None = None
        for name, values in self.channels.items():
            if name not in CHANNELS:
                raise RecordError(f"unknown channel {name!r}; known channels: {', '.join(CHANNELS)}")
            arr = np.asarray(values, dtype=float)
            if arr.ndim == 1:
                require_length(arr.shape[0], f"channel {name!r}")
            if arr.ndim != 1 or arr.shape[0] < 2:
                raise RecordError(f"channel {name!r} has shape {arr.shape}; it must be a list of samples (at least 2)")
            if n is None:
                n = arr.shape[0]
            elif arr.shape[0] != n:
                first = next(iter(clean))
                raise RecordError(
                    f"channel {name!r} has {arr.shape[0]} samples and channel {first!r} {n}; every channel "
                    f"needs the same number of samples"
                )
            if not np.all(np.isfinite(arr)):
                bad = int(np.flatnonzero(~np.isfinite(arr))[0])
                raise RecordError(f"channel {name!r} holds a non-finite value (NaN or inf) at sample {bad}")
            if arr.flags.writeable or not arr.flags.owndata:  # else read-only and its own: nothing writes it
                arr = arr.copy()
                arr.flags.writeable = False
            clean[name] = arr
        object.__setattr__(self, "channels", {c: clean[c] for c in CHANNELS if c in clean})  # canonical order
        object.__setattr__(self, "conditions", {k: float(v) for k, v in dict(self.conditions).items()})
        units = {c: str(u) for c, u in dict(self.units).items() if u != CHANNEL_UNITS.get(c)}
        try:
            for c, u in units.items():
                if c not in clean:
                    raise UnitError(f"units are given for channel {c!r}, which the record does not hold")
                factor(c, u, self.conditions)
        except UnitError as exc:
            raise RecordError(str(exc)) from None
        for c, arr in clean.items():  # values no computation survives: refused, naming channel and sample
            given = f" (given in {units[c]})" if c in units else ""
            require_magnitude(arr, f"channel {c!r}{given}", CHANNEL_UNITS[c])
        object.__setattr__(self, "units", units)
        try:
            grid = SampleGrid(self.sample_interval, n or 0, self.event_index)
            grid.require_test_window()
        except GridError as exc:
            raise ProtocolError(str(exc)) from None
        object.__setattr__(self, "sample_interval", grid.sample_interval)
        object.__setattr__(self, "event_index", grid.event_index)
        if self.excerpt is not None and not (
            self.excerpt.first >= 0 and self.excerpt.first + grid.n_samples <= self.excerpt.n_samples
        ):
            raise RecordError(
                f"an excerpt of {grid.n_samples} samples cannot start at sample {self.excerpt.first} of a record of "
                f"{self.excerpt.n_samples}"
            )

    # -- the grid ---------------------------------------------------------------------
    @property
    def n_samples(self) -> int:
        """Samples per channel."""
        return next(iter(self.channels.values())).shape[0]

    @property
    def grid(self) -> SampleGrid:
        """The record's sample grid."""
        return SampleGrid(self.sample_interval, self.n_samples, self.event_index)

    @property
    def time(self) -> np.ndarray:
        """Sample times relative to the event, t - t_e [s]."""
        return self.grid.time

    @property
    def origin(self) -> Excerpt:
        """Where this record lies in the record as it was read (itself, from sample 0, unless an excerpt)."""
        return self.excerpt if self.excerpt is not None else Excerpt(0, self.n_samples)

    def replace(self, **changes: Any) -> Record:
        """Copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def with_channels(self, channels: Mapping[str, np.ndarray], grid: SampleGrid | None = None) -> Record:
        """A record of other samples (model units) on ``grid`` (default: this one) that keeps this one's units.

        Used for simulations meant to be overlaid on this record (e.g. before and after a fix).
        """
        g = self.grid if grid is None else grid
        return Record(
            channels=channels,
            sample_interval=g.sample_interval,
            event_index=g.event_index,
            conditions=self.conditions,
            units={c: u for c, u in self.units.items() if c in channels},
            event_location=self.event_location if g == self.grid else None,
            excerpt=self.excerpt if g == self.grid else None,
        )

    def test_window(self) -> tuple[Record, WindowUse]:
        """The record cut to the test window (4.8 ms before to 200 ms after the event), and which samples that is.

        Every analysis (identification, calibration, diagnosis) reads this window; a longer
        record's other samples are ignored and :class:`WindowUse` says so, counting samples in the
        record as it was read (:attr:`origin`).
        """
        win = self.grid.window()
        ts = self.sample_interval
        origin = self.origin
        use = WindowUse(
            origin.first + win.start,
            origin.first + win.stop,
            origin.n_samples,
            (win.start - self.event_index) * ts,
            (win.stop - self.event_index) * ts,
        )
        if win.start == 0 and win.stop == self.n_samples:
            return self, use
        cut = {c: x[win] for c, x in self.channels.items()}
        excerpt = None if self.excerpt is None else Excerpt(origin.first + win.start, origin.n_samples)
        return dataclasses.replace(self, channels=cut, event_index=self.event_index - win.start, excerpt=excerpt), use

    # -- access -------------------------------------------------------------------------
    def __getitem__(self, channel: str) -> np.ndarray:
        try:
            return self.channels[channel]
        except KeyError:
            raise RecordError(
                f"channel {channel!r} is not in this record; it holds: {', '.join(self.channels)}"
            ) from None

    def unit(self, channel: str) -> str:
        """The unit ``channel`` was given in (its model unit unless ``units`` says otherwise)."""
        return self.units.get(channel, CHANNEL_UNITS[channel])

    # -- the service's JSON record format -------------------------------------------------
    def to_dict(self) -> dict:
        """JSON-ready dict in the service's record format, the samples in the record's own units."""
        values = from_model_units(self.channels, self.units, self.conditions)
        out: dict = {
            "sample_interval": self.sample_interval,
            "event_index": self.event_index,
            "channels": {k: v.tolist() for k, v in values.items()},
            "conditions": dict(self.conditions),
        }
        if self.units:
            out["units"] = dict(self.units)
        if self.event_time is not None:
            out["event_time"] = self.event_time
        if self.event_location is not None:
            out["event_location"] = self.event_location.to_dict()
        return out

    @classmethod
    def from_dict(cls, data: Mapping, *, default_interval: float | None = None) -> Record:
        """Build a record from the service's JSON record format (see :func:`engine.records.protocol.record_from_data`).

        ``default_interval`` [s]: the sample interval of a record that gives neither ``sample_interval`` nor ``t``
        (the protocol interval of the drive it was taken on, when one is given); default MODEL.md's 0.1 ms.
        """
        from engine.records.protocol import record_from_data  # the boundary; imports this module

        if "channels" not in data:
            raise RecordError("a record needs a 'channels' object mapping channel names to sample lists")
        index = data.get("event_index")
        located = data.get("event_location")
        record = record_from_data(
            channels=dict(data["channels"]),
            sample_interval=data.get("sample_interval"),
            event_index=None if index is None else index,
            conditions=dict(data.get("conditions") or {}),
            units=dict(data.get("units") or {}),
            time=data.get("t"),
            event_time=data.get("event_time"),
            default_interval=default_interval,
        )
        if located is not None and index is not None:  # written by to_dict: the event was located, keep saying so
            try:
                loc = EventLocation(
                    int(located["index"]),
                    (float(located["interval"][0]), float(located["interval"][1])),
                    float(located["sigma"]),
                    str(located["channel"]),
                    str(located["method"]),
                )
            except (KeyError, TypeError, ValueError, IndexError):
                raise RecordError(
                    "event_location must be as a record's to_dict writes it: index, interval [2 numbers], sigma, "
                    "channel, method"
                ) from None
            if loc.index != record.event_index:
                raise RecordError(
                    f"event_location.index {loc.index} contradicts event_index {record.event_index}; drop one of them"
                )
            record = dataclasses.replace(record, event_location=loc)
        return record
