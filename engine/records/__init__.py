"""The record protocol: what a backlash-test record is, and the one boundary where a bench's record is read.

* :mod:`~engine.records.record`: :class:`Record` (model units, any grid) and :class:`WindowUse`.
* :mod:`~engine.records.grid`: :class:`SampleGrid`, the test window, MODEL.md's :data:`PROTOCOL_GRID`.
* :mod:`~engine.records.units`: accepted units and their factors (one place).
* :mod:`~engine.records.event`: locating the event from the data.
* :mod:`~engine.records.protocol`: :func:`record_from_data`, the boundary.
* :mod:`~engine.records.resample`: a record on MODEL.md's grid for pattern sets (scipy.signal.resample_poly).
"""

from engine.records.errors import ProtocolError, RecordError
from engine.records.event import EventLocation, locate_event
from engine.records.grid import PROTOCOL_GRID, GridError, SampleGrid
from engine.records.protocol import interval_from_time, record_from_data
from engine.records.record import Record, WindowUse
from engine.records.resample import resample_to_grid, to_protocol_grid
from engine.records.units import UNITS, UnitError

__all__ = [
    "PROTOCOL_GRID",
    "UNITS",
    "EventLocation",
    "GridError",
    "ProtocolError",
    "Record",
    "RecordError",
    "SampleGrid",
    "UnitError",
    "WindowUse",
    "interval_from_time",
    "locate_event",
    "record_from_data",
    "resample_to_grid",
    "to_protocol_grid",
]
