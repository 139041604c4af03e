"""The record protocol: what a backlash-test record is, and the one boundary where a bench's record is read.

* :mod:`~engine.records.record`: :class:`Record` (model units, any grid) and :class:`WindowUse`.
* :mod:`~engine.records.grid`: :class:`SampleGrid`, the test window, MODEL.md's :data:`PROTOCOL_GRID`.
* :mod:`~engine.records.units`: accepted units and their factors (one place).
* :mod:`~engine.records.event`: locating the event from the data.
* :mod:`~engine.records.protocol`: :func:`record_from_data`, the boundary.
* :mod:`~engine.records.streamed`: :func:`record_from_chunks`, the boundary for a record read in pieces: a long
  one is never held whole, only its :class:`Excerpt` around the event (the time column checked in pieces by
  :mod:`~engine.records.time_column`, the columns kept on disk meanwhile by :mod:`~engine.records.spill`, read
  in pieces through :mod:`~engine.records.series`, the median of the event locator selected exactly in
  bounded memory by :mod:`~engine.records.order`).
* :mod:`~engine.records.resample`: a record on MODEL.md's grid for pattern sets (scipy.signal.resample_poly).
"""

from engine.records.errors import ProtocolError, RecordError
from engine.records.event import EventLocation, locate_event
from engine.records.grid import PROTOCOL_GRID, GridError, SampleGrid
from engine.records.protocol import interval_from_time, record_from_data
from engine.records.record import Excerpt, Record, WindowUse
from engine.records.resample import resample_to_grid, to_protocol_grid
from engine.records.streamed import record_from_chunks
from engine.records.units import UNITS, UnitError

__all__ = [
    "PROTOCOL_GRID",
    "UNITS",
    "EventLocation",
    "Excerpt",
    "GridError",
    "ProtocolError",
    "Record",
    "RecordError",
    "SampleGrid",
    "UnitError",
    "WindowUse",
    "interval_from_time",
    "locate_event",
    "record_from_chunks",
    "record_from_data",
    "resample_to_grid",
    "to_protocol_grid",
]
