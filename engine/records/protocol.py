"""The record boundary: a record as a bench gives it, read once into a :class:`~engine.records.record.Record`.

Everything about how a record was taken is settled here and nowhere else:

* **interval**: ``sample_interval`` [s] (10 us to 1 ms), or a time column ``t`` [s]
  whose (uniform) spacing defines it; given both, they must agree.
* **length**: any number of samples, the same for every channel, covering at
  least 4.8 ms before the event and 200 ms from it on (else a
  :class:`~engine.records.errors.ProtocolError` that says how much is missing).
  Analyses read the test window of it (:meth:`Record.test_window`) and say which
  samples that was.
* **alignment**: ``event_index`` when given; else the event is located from the
  data (:func:`engine.records.event.locate_event`) and the record carries the
  :class:`~engine.records.event.EventLocation`.
* **units**: per channel (:mod:`engine.records.units`), converted to MODEL.md's
  units here, once.

The record is held whole, in one float64 array per channel: the arrays made here (from lists, or by a
unit's factor) are kept by the :class:`~engine.records.record.Record` as they are, a caller's array in
its model unit is copied once; the checks and the event locator make no temporary float array as long
as the record, only boolean masks (:mod:`engine.records.event` reads it in pieces). A record too long to
hold is read in pieces instead (:func:`engine.records.streamed.record_from_chunks`, the CSV reader's way).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from engine.constants import CHANNELS, SAMPLE_INTERVAL
from engine.records.errors import RecordError
from engine.records.event import locate_event
from engine.records.record import Record
from engine.records.time_column import TIME_TOLERANCE, TimeSteps, sample_interval_of
from engine.records.units import UnitError, to_model_units

__all__ = ["TIME_TOLERANCE", "interval_from_time", "record_from_data"]


def interval_from_time(t: Sequence[float] | np.ndarray) -> float:
    """Sample interval [s] defined by a time column [s] (uniform, increasing; :mod:`engine.records.time_column`).

    Raises
    ------
    RecordError
        Fewer than two values, a non-finite value, time not increasing, or steps that
        differ by more than ``TIME_TOLERANCE`` of the step (the record would be misread
        as uniformly sampled: resample it first).
    """
    try:
        arr = np.asarray(t, dtype=float)
    except (TypeError, ValueError):
        raise RecordError("the time column 't' must be a list of numbers (seconds)") from None
    if arr.ndim != 1 or arr.size < 2:
        raise RecordError(f"the time column 't' needs at least 2 values, got shape {arr.shape}")
    steps = TimeSteps()
    steps.add(arr)
    return steps.interval(again=lambda: (arr,))


def _arrays(channels: Mapping[str, Any]) -> dict[str, np.ndarray]:
    if not isinstance(channels, Mapping) or not channels:
        raise RecordError("a record needs at least one channel; known channels: " + ", ".join(CHANNELS))
    out = {}
    for name, values in channels.items():
        if name not in CHANNELS:
            raise RecordError(f"unknown channel {name!r}; known channels: {', '.join(CHANNELS)}")
        try:
            arr = np.asarray(values, dtype=float)
        except (TypeError, ValueError):
            raise RecordError(f"channel {name!r} must be a list of numbers") from None
        if arr.ndim != 1:
            raise RecordError(f"channel {name!r} has shape {arr.shape}; it must be a list of samples")
        if not np.all(np.isfinite(arr)):
            bad = int(np.flatnonzero(~np.isfinite(arr))[0])
            raise RecordError(f"channel {name!r} holds a non-finite value (NaN or inf) at sample {bad}")
        out[name] = arr
    lengths = {n: a.size for n, a in out.items()}
    if len(set(lengths.values())) > 1:
        raise RecordError(
            "every channel needs the same number of samples; got " + ", ".join(f"{n}: {k}" for n, k in lengths.items())
        )
    return out


def record_from_data(
    channels: Mapping[str, Any],
    sample_interval: float | None = None,
    event_index: int | None = None,
    conditions: Mapping[str, float] | None = None,
    units: Mapping[str, str] | None = None,
    time: Sequence[float] | np.ndarray | None = None,
    event_time: float | None = None,
    *,
    default_interval: float | None = None,
) -> Record:
    """Read a record as a bench gives it (see the module notes).

    Parameters
    ----------
    channels : mapping of str to sequence of float
        Non-empty subset of ``a1, m_el, omega1, a2, v2``, in the units ``units`` says.
    sample_interval : float, optional
        Ts [s]; from ``time`` when omitted, else ``default_interval``.
    event_index : int, optional
        Index of the sample at the event; located from m_el or a1 when omitted.
    conditions : mapping of str to float, optional
        Known operating point (``K``, ``J1``, ``c``, ``c1``; ``base_torque`` [N*m] for m_el in N*m).
    units : mapping of str to str, optional
        Unit per channel (see :data:`engine.records.units.UNITS`); MODEL.md's by default.
    time : sequence of float, optional
        Sample times [s] (a CSV's ``t`` column); defines the interval.
    event_time : float, optional
        t_e since switch-on [s], when known.
    default_interval : float, optional
        Ts [s] of a record that gives neither ``sample_interval`` nor ``time``: the protocol interval of the
        drive it was taken on, when one is given (``DriveDescription.grid().sample_interval``). Default:
        MODEL.md's 0.1 ms (:data:`~engine.constants.SAMPLE_INTERVAL`).

    Returns
    -------
    Record
        In MODEL.md's units, remembering ``units``.

    Raises
    ------
    RecordError
        Malformed channels, unknown units (the message names the accepted ones), a bad
        time column, or an interval that contradicts it.
    ProtocolError
        Interval outside 10 us - 1 ms, too little time around the event, or an event that
        cannot be located (give ``event_index``).
    """
    arrays = _arrays(channels)
    conditions = {k: float(v) for k, v in dict(conditions or {}).items()}
    units = {str(k): str(v) for k, v in dict(units or {}).items()}
    n = next(iter(arrays.values())).size
    from_time = None
    if time is not None:
        from_time = interval_from_time(time)
        if len(time) != n:
            raise RecordError(f"the time column 't' has {len(time)} values and the channels {n} samples")
    default = SAMPLE_INTERVAL if default_interval is None else default_interval
    ts = sample_interval_of(from_time, sample_interval, default)
    try:
        model = to_model_units(arrays, units, conditions)
    except UnitError as exc:
        raise RecordError(str(exc)) from None
    for name, arr in model.items():  # arrays made here, not the caller's: the record keeps them, uncopied
        if arr is not arrays[name] or (arr is not channels[name] and arr.base is None):
            arr.flags.writeable = False
    location = None
    if event_index is None:
        location = locate_event(model, ts)
        index = location.index
    else:
        if float(event_index) != int(event_index):
            raise RecordError(f"event_index must be a whole sample index, got {event_index}")
        index = int(event_index)
    return Record(
        channels=model,
        sample_interval=ts,
        event_index=index,
        conditions=conditions,
        event_time=None if event_time is None else float(event_time),
        units=units,
        event_location=location,
    )
