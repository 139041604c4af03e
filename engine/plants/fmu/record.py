"""A record of a plant from an FMU: a time column, the driven inputs' columns and the measured channels.

The CSV form has one header line naming the columns the plant's description asks for (its
``time`` column, every driven input's ``column`` and every channel's ``name``; other columns are
ignored), optionally with units in brackets (``a_body [m/s2]``), then one row of numbers per
sample. Comment lines start with ``#``. A unit in the header that differs from the description's is
refused, not converted: the record is read in the description's units or not at all. Without a
unit in the header the description's unit is taken (the plant's documentation says so).

Refused with a message that says what to fix (:class:`~engine.records.RecordError`): a missing
column, a row that is not numbers, a non-finite value (named by column and row), time that does not
increase, fewer than :data:`MIN_SAMPLES` samples, more than the records' limit, a magnitude beyond
the records' limit, a first sample before the FMU's start time.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import numpy as np

from engine.plants.fmu.description import PlantDescription
from engine.records import RecordError
from engine.records.csv_table import numeric_rows, table_lines
from engine.records.limits import require_length, require_magnitude

__all__ = ["MIN_SAMPLES", "FmuRecord", "check_units", "load_record", "record_from_columns", "record_from_table"]

#: Fewest samples a record needs.
MIN_SAMPLES: int = 50
_HEADER = re.compile(r"^\s*([^\[\]]+?)\s*(?:\[\s*([^\]]*?)\s*\])?\s*$")


@dataclass(frozen=True, eq=False)
class FmuRecord:
    """One record: sample instants [s] and columns, in the description's units.

    Attributes
    ----------
    name : str
        Where it came from (a file's stem).
    t : ndarray, shape (n,)
        Sample instants [s] on the FMU's time axis, increasing.
    columns : mapping of str to ndarray
        Every driven input's and channel's samples by column name.
    """

    name: str
    t: np.ndarray
    columns: Mapping[str, np.ndarray] = field(default_factory=dict)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.size)

    @property
    def ts(self) -> float:
        """Median sample interval [s]."""
        return float(np.median(np.diff(self.t)))

    def replace_columns(self, columns: Mapping[str, np.ndarray], name: str | None = None) -> FmuRecord:
        """The same record with some columns replaced (a synthetic record's channels)."""
        merged = {**self.columns, **{k: np.asarray(v, dtype=float) for k, v in columns.items()}}
        return FmuRecord(name or self.name, self.t, MappingProxyType(merged))


def record_from_columns(
    description: PlantDescription, t: np.ndarray, columns: Mapping[str, np.ndarray], name: str = "record"
) -> FmuRecord:
    """A checked record from arrays in the description's units.

    Raises
    ------
    RecordError
        For anything the module docstring lists.
    """
    need = [i.column for i in description.driven] + [c.name for c in description.channels]
    missing = [c for c in need if c not in columns]
    if missing:
        raise RecordError(f"{name}: the record lacks the column(s) {missing} the plant {description.name!r} reads")
    t = np.asarray(t, dtype=float)
    require_length(t.size, name)
    if t.ndim != 1 or t.size < MIN_SAMPLES:
        raise RecordError(f"{name}: a record needs at least {MIN_SAMPLES} samples, got {t.size}")
    data: dict[str, np.ndarray] = {}
    for col in [description.time, *(str(c) for c in need)]:
        x = t if col == description.time else np.asarray(columns[col], dtype=np.float64)
        if x.shape != t.shape:
            raise RecordError(f"{name}: column {col!r} has {x.size} samples, the time column {t.size}")
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            raise RecordError(f"{name}: column {col!r} is not finite at row {int(bad[0]) + 1} ({x[bad[0]]})")
        require_magnitude(x, f"{name}: column {col!r}", "")
        if col != description.time:
            data[col] = x
    dt = np.diff(t)
    if np.any(dt <= 0.0):
        k = int(np.argmax(dt <= 0.0))
        raise RecordError(f"{name}: time does not increase at row {k + 2} ({t[k]} then {t[k + 1]} s)")
    if t[0] < description.start_time:
        raise RecordError(
            f"{name}: the first sample (t = {t[0]} s) lies before the FMU's start time {description.start_time} s; "
            "the record's time column must be on the FMU's time axis"
        )
    for x in data.values():
        x.flags.writeable = False
    t.flags.writeable = False
    return FmuRecord(name, t, MappingProxyType(data))


def _expected_units(description: PlantDescription) -> dict[str, str]:
    """The record's columns (time, driven inputs, channels) -> their units in the description."""
    expected = {description.time: "s"}
    expected.update({str(i.column): i.unit for i in description.driven})
    expected.update({c.name: c.unit for c in description.channels})
    return expected


def check_units(description: PlantDescription, units: Mapping[str, str], name: str = "record") -> None:
    """Refuse a column whose stated unit differs from the description's (a record is never converted).

    Raises
    ------
    RecordError
        Naming the column, the unit stated and the unit the plant reads it in.
    """
    expected = _expected_units(description)
    for col, unit in units.items():
        if col in expected and expected[col] and unit != expected[col]:
            raise RecordError(
                f"{name}: column {col!r} is in {unit!r}; the plant {description.name!r} reads it in "
                f"{expected[col]!r}: convert it (the record is not converted, to be never misread)"
            )


def record_from_table(
    description: PlantDescription,
    columns: Mapping[str, np.ndarray | list[float]],
    units: Mapping[str, str] | None = None,
    name: str = "record",
) -> FmuRecord:
    """A checked record from its columns by name (the time column among them), units stated or not.

    Raises
    ------
    RecordError
        A unit other than the description's (:func:`check_units`), no time column, or anything
        :func:`record_from_columns` refuses.
    """
    check_units(description, units or {}, name)
    if description.time not in columns:
        raise RecordError(f"{name}: the record lacks the time column {description.time!r}")
    wanted = _expected_units(description)
    arrays = {k: np.asarray(v, dtype=float) for k, v in columns.items() if k in wanted}
    return record_from_columns(description, arrays.pop(description.time), arrays, name)


def load_record(path: str | Path | bytes, description: PlantDescription, name: str | None = None) -> FmuRecord:
    """Read a record in the CSV form (module docstring).

    Raises
    ------
    RecordError
        A file that cannot be read correctly as a record of this plant; the message says what to fix.
    """
    if isinstance(path, bytes):
        text, label = path.decode("utf-8", errors="replace"), name or "record"
    else:
        p = Path(path)
        if p.suffix.lower() != ".csv":
            raise RecordError(f"{p}: a record of an FMU plant is a .csv file")
        try:
            text = p.read_text(encoding="utf-8-sig", errors="replace")
        except OSError as exc:
            raise RecordError(f"cannot read {p}: {exc.strerror or exc}") from None
        label = name or p.stem
    body = table_lines(text)
    if len(body) < 2:
        raise RecordError(f"{label}: the CSV needs a header line and at least one row")
    header: list[str] = []
    units: dict[str, str] = {}
    for h in body[0].split(","):
        m = _HEADER.match(h)
        col = (m.group(1) if m else h).strip()
        header.append(col)
        if m and m.group(2) is not None:
            units[col] = m.group(2)
    check_units(description, units, label)
    expected = _expected_units(description)
    absent = [c for c in expected if c not in header]
    if absent:
        raise RecordError(f"{label}: the CSV header {header} lacks the column(s) {absent}")
    rows = numeric_rows(body[1:], len(header), label)
    columns = {c: rows[:, header.index(c)] for c in expected if c != description.time}
    return record_from_columns(description, rows[:, header.index(description.time)], columns, label)
