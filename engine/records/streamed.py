"""The record boundary for a record read in pieces: a long capture checked, located and cut as it is read.

A bench's capture may run for minutes around one backlash test; every analysis reads only the test
window around its event (and the plausibility checks a stretch ten times as long). :func:`record_from_chunks`
reads such a record a chunk at a time (the CSV reader, :mod:`app.records_io`, hands it rows as they are
parsed) and keeps only that stretch, so memory is bounded by the test window and a chunk, not by the
record's length (issue 54):

* a record of at most :data:`HOLD_SAMPLES` samples is held whole and read by
  :func:`~engine.records.protocol.record_from_data`, exactly as before;
* a longer one is checked chunk by chunk (every sample finite and within
  :data:`~engine.records.limits.MAX_ABS_SAMPLE` in the model's unit, the time column uniform:
  :class:`~engine.records.time_column.TimeSteps`), converted to the model's units, and written to
  temporary files (:class:`~engine.records.spill.Spill`: 8 bytes per sample and column on disk, deleted
  once the record is read); then its event is located from the files (:func:`~engine.records.event.locate_event`,
  which reads them in pieces and gives the very index it gives the record held whole), the grid is
  checked, and the *excerpt* is read back: :data:`READ_SPAN` times the test window around the event and
  :data:`MARGIN_SAMPLES` more on either side, within the record. The :class:`~engine.records.record.Record`
  holds that excerpt, and :class:`~engine.records.record.Excerpt` says where it lies in the record read.

A long record is refused for what the whole record would be refused for, in the same words (faults are
reported in the order :func:`~engine.records.protocol.record_from_data` checks them; a value that
overflows in the model's unit before the event is located), except that it is not capped at
:data:`~engine.records.limits.MAX_SAMPLES`: the cap bounds what a record held whole costs, and this one
is not held. Every analysis of the excerpt gives the answer it gives on the whole record: the diagnosis
and the identification read the test window (the identification's resampling at most
:data:`MARGIN_SAMPLES` beyond it), the plausibility checks at most :data:`READ_SPAN` times it. One
exception: a record that starts (or ends) less than :func:`~engine.records.resample.reach` samples (at
most 1.2 ms) beyond its test window is resampled for the identification with scipy's extension of its
ends, a line from its first sample to its last, which the excerpt does not hold; the first (last) one
to seven resampled samples of the window then differ slightly (by 1e-5 to 1e-4 on a random walk of
amplitude 100 in a test), and the identification's figures with them.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping

import numpy as np

from engine.constants import CHANNEL_UNITS, CHANNELS, POST_EVENT_TIME, PRE_EVENT_TIME, SAMPLE_INTERVAL
from engine.records.errors import ProtocolError, RecordError
from engine.records.event import EventLocation, locate_event
from engine.records.grid import GridError, SampleGrid, samples_for
from engine.records.limits import first_beyond, magnitude_error
from engine.records.protocol import record_from_data
from engine.records.record import Excerpt, Record
from engine.records.series import pieces
from engine.records.spill import Spill
from engine.records.time_column import TimeSteps, sample_interval_of
from engine.records.units import UnitError, factor, to_model_units

__all__ = ["HOLD_SAMPLES", "MARGIN_SAMPLES", "READ_SPAN", "Chunk", "record_from_chunks"]

#: A chunk of a record: its channels' next samples (as given, in the record's units) and the time
#: column's [s] (None for a record without one); the same number of samples each.
Chunk = tuple[Mapping[str, np.ndarray], np.ndarray | None]

#: Samples per channel up to which a record read in pieces is held whole (6.5 s at 0.1 ms; 3.1 MB for
#: five channels and a time column).
HOLD_SAMPLES: int = 1 << 16
#: How many times the test window's span, around the event, the analyses read: the plausibility checks
#: read a record at a tenth of its sample interval (``engine.diagnosis.plausibility.TIME_FACTORS``).
READ_SPAN: float = 10.0
#: Samples kept beyond that on either side: the resampler's filter reaches 10 x max(1, 0.1 ms / Ts) + 8 <= 108
#: samples beyond the test window (``engine.records.resample``).
MARGIN_SAMPLES: int = 128

_TIME = "t"


def record_from_chunks(
    chunks: Iterable[Chunk],
    sample_interval: float | None = None,
    event_index: int | None = None,
    conditions: Mapping[str, float] | None = None,
    units: Mapping[str, str] | None = None,
    event_time: float | None = None,
    *,
    hold: int | None = None,
    default_interval: float | None = None,
) -> Record:
    """Read a record given a chunk at a time (see the module notes).

    Parameters
    ----------
    chunks : iterable of Chunk
        The record's consecutive chunks, each its channels' next samples (the same channels every time, in
        the units ``units`` says) and, when the record has one, the time column's [s].
    sample_interval, event_index, conditions, units, event_time
        As :func:`~engine.records.protocol.record_from_data` takes them.
    hold : int, optional
        Samples up to which the record is held whole (default :data:`HOLD_SAMPLES`).
    default_interval : float, optional
        Ts [s] of a record with neither ``sample_interval`` nor a time column (the protocol interval of the
        drive it was taken on, when one is given); default MODEL.md's 0.1 ms. As
        :func:`~engine.records.protocol.record_from_data` takes it.

    Returns
    -------
    Record
        The whole record when it has at most ``hold`` samples, else its excerpt (``record.excerpt``).

    Raises
    ------
    RecordError, ProtocolError
        What :func:`~engine.records.protocol.record_from_data` raises for the whole record (but the cap on
        its length), and an error of the chunks' reader as it comes.
    """
    hold = HOLD_SAMPLES if hold is None else hold
    stream = iter(chunks)
    held: list[Chunk] = []
    n = 0
    for chunk in stream:
        held.append(chunk)
        n += _length(chunk)
        if n > hold:
            break
    else:
        return _whole(held, sample_interval, event_index, conditions, units, event_time, default_interval)
    with Spill([*held[0][0], *([_TIME] if held[0][1] is not None else [])]) as spill:
        reader = _LongRecord(spill, sample_interval, event_index, conditions, units, event_time, default_interval)
        return reader.read(held, stream)


def _length(chunk: Chunk) -> int:
    channels, time = chunk
    lengths = {np.shape(x)[0] if np.ndim(x) else 0 for x in channels.values()}
    if time is not None:
        lengths.add(np.shape(time)[0] if np.ndim(time) else 0)
    if len(lengths) > 1:
        raise RecordError(
            "every channel (and the time column) needs the same number of samples; a chunk of the record holds "
            + " and ".join(str(k) for k in sorted(lengths))
        )
    return lengths.pop() if lengths else 0


def _whole(
    held: list[Chunk],
    sample_interval: float | None,
    event_index: int | None,
    conditions: Mapping[str, float] | None,
    units: Mapping[str, str] | None,
    event_time: float | None,
    default_interval: float | None = None,
) -> Record:
    """A short record, joined and read by the one boundary of records held whole."""
    names = list(held[0][0]) if held else []
    channels = {name: np.concatenate([np.asarray(c[name], dtype=float) for c, _ in held]) for name in names}
    has_time = bool(held) and held[0][1] is not None
    time = np.concatenate([np.asarray(t, dtype=float) for _, t in held if t is not None]) if has_time else None
    return record_from_data(
        channels, sample_interval, event_index, conditions, units, time, event_time, default_interval=default_interval
    )


class _LongRecord:
    """The checks of a long record as its chunks come, and what is done with it once they have all come."""

    def __init__(
        self,
        spill: Spill,
        sample_interval: float | None,
        event_index: int | None,
        conditions: Mapping[str, float] | None,
        units: Mapping[str, str] | None,
        event_time: float | None,
        default_interval: float | None = None,
    ) -> None:
        self.spill = spill
        self.names = [name for name in spill.columns if name != _TIME]
        self.has_time = _TIME in spill.columns
        self.sample_interval = sample_interval
        self.default_interval = SAMPLE_INTERVAL if default_interval is None else default_interval
        self.event_index = event_index
        self.conditions = {k: float(v) for k, v in dict(conditions or {}).items()}
        self.units = {str(k): str(v) for k, v in dict(units or {}).items()}
        self.event_time = None if event_time is None else float(event_time)
        self.n = 0
        self.steps = TimeSteps()
        self.non_finite: dict[str, int] = {}  # first non-finite sample per channel, as given
        self.overflow: dict[str, int] = {}  # first non-finite sample per channel in the model's unit
        self.too_large: dict[str, tuple[int, float]] = {}  # first sample beyond the limit, and its value
        for name in self.names:
            if name not in CHANNELS:
                raise RecordError(f"unknown channel {name!r}; known channels: {', '.join(CHANNELS)}")
        self.unit_error: RecordError | None = None
        self.factors: dict[str, float] = {}
        try:  # the messages of the record held whole: to_model_units on no samples
            to_model_units({name: np.empty(0) for name in self.names}, self.units, self.conditions)
            self.factors = {c: factor(c, self.units.get(c, CHANNEL_UNITS[c]), self.conditions) for c in self.names}
        except UnitError as exc:
            self.unit_error = RecordError(str(exc))

    def read(self, held: list[Chunk], rest: Iterator[Chunk]) -> Record:
        for chunk in held:
            self._take(chunk)
        held.clear()
        for chunk in rest:
            self._take(chunk)
        return self._record()

    def _take(self, chunk: Chunk) -> None:
        """Check one chunk and write it (in the model's units) to the spill."""
        channels, time = chunk
        if list(channels) != self.names or (time is not None) != self.has_time:
            raise ValueError("every chunk of a record must hold the same channels (and time column) as the first")
        size = _length(chunk)
        out: dict[str, np.ndarray] = {}
        for name in self.names:
            x = np.asarray(channels[name], dtype=float)
            if name not in self.non_finite and not np.all(np.isfinite(x)):
                self.non_finite[name] = self.n + int(np.flatnonzero(~np.isfinite(x))[0])
            f = self.factors.get(name, 1.0)
            model = x if f == 1.0 else x * f
            if name not in self.overflow and not np.all(np.isfinite(model)):
                self.overflow[name] = self.n + int(np.flatnonzero(~np.isfinite(model))[0])
            if name not in self.too_large and name not in self.overflow:
                i = first_beyond(model)
                if i is not None:
                    self.too_large[name] = (self.n + i, float(model[i]))
            out[name] = model
        if time is not None:
            t = np.asarray(time, dtype=float)
            self.steps.add(t)
            out[_TIME] = t
        self.spill.append(out)
        self.n += size

    def _record(self) -> Record:
        """The checks of the whole record, in :func:`record_from_data`'s order; then the excerpt."""
        for name in self.names:
            if name in self.non_finite:
                raise RecordError(
                    f"channel {name!r} holds a non-finite value (NaN or inf) at sample {self.non_finite[name]}"
                )
        ts = self._interval()
        if self.unit_error is not None:
            raise self.unit_error
        for name in self.names:  # before the event is located from them (record_from_data: in Record)
            if name in self.overflow:
                raise RecordError(
                    f"channel {name!r} holds a non-finite value (NaN or inf) at sample {self.overflow[name]}"
                )
        location: EventLocation | None = None
        if self.event_index is None:
            located = {c: self.spill.columns[c] for c in self.names}
            location = locate_event(located, ts)
            index = location.index
        else:
            if float(self.event_index) != int(self.event_index):
                raise RecordError(f"event_index must be a whole sample index, got {self.event_index}")
            index = int(self.event_index)
        given_in = {c: u for c, u in self.units.items() if u != CHANNEL_UNITS.get(c)}
        for name in self.names:
            if name in self.too_large:
                given = f" (given in {given_in[name]})" if name in given_in else ""
                raise magnitude_error(f"channel {name!r}{given}", CHANNEL_UNITS[name], *self.too_large[name])
        try:
            grid = SampleGrid(ts, self.n, index)
            grid.require_test_window()
        except GridError as exc:
            raise ProtocolError(str(exc)) from None
        return self._excerpt(grid, location)

    def _interval(self) -> float:
        """The sample interval [s]: record_from_data's rules."""
        from_time = None
        if self.has_time:
            column = self.spill.columns[_TIME]
            from_time = self.steps.interval(again=lambda: (piece for _, piece in pieces(column)))
        return sample_interval_of(from_time, self.sample_interval, self.default_interval)

    def _excerpt(self, grid: SampleGrid, location: EventLocation | None) -> Record:
        """What the analyses read of the record: the excerpt around its event, read back from the spill."""
        ts, index = grid.sample_interval, grid.event_index
        before = samples_for(READ_SPAN * PRE_EVENT_TIME, ts) + MARGIN_SAMPLES
        after = samples_for(READ_SPAN * POST_EVENT_TIME, ts) + MARGIN_SAMPLES
        first, stop = max(0, index - before), min(self.n, index + after)
        channels = {}
        for name in self.names:
            values = self.spill.columns[name].read(first, stop)
            values.flags.writeable = False  # made here: the record keeps it, uncopied
            channels[name] = values
        return Record(
            channels=channels,
            sample_interval=ts,
            event_index=index - first,
            conditions=self.conditions,
            event_time=self.event_time,
            units=self.units,
            event_location=location,
            excerpt=Excerpt(first, self.n),
        )
