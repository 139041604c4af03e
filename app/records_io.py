"""Records as text and files: the service's JSON record format and its CSV form.

JSON is :meth:`engine.records.Record.to_dict` / ``from_dict``. The CSV form has a
header row of channel names (a non-empty subset of ``a1, m_el, omega1, a2, v2``)
and one row per sample; ``sample_interval`` and ``event_index`` travel beside it
(query parameters over HTTP, options on the command line).

The CSV form is a wire format of the service and the CLI (both in ``app``); the
engine only knows :class:`~engine.records.Record`, so the codec lives here.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from engine.constants import CHANNELS, EVENT_INDEX, N_SAMPLES, SAMPLE_INTERVAL
from engine.records import Record, RecordError


class RecordFormatError(ValueError):
    """Raised for text that is not a record in JSON or CSV form; the message says what to fix."""


# -- CSV ------------------------------------------------------------------------


def record_from_csv(
    text: str,
    sample_interval: float = SAMPLE_INTERVAL,
    event_index: int = EVENT_INDEX,
    conditions: Mapping[str, float] | None = None,
) -> Record:
    """Parse the CSV form of a record.

    Raises
    ------
    RecordFormatError
        Malformed CSV (no header, duplicate column, ragged rows, a field that is
        not a number).
    engine.records.RecordError
        Well-formed CSV that is not a valid record (unknown channel, wrong
        number of samples, NaN or inf).
    """
    if not text.strip():
        raise RecordFormatError(
            f"the CSV is empty; send a header row of channel names ({', '.join(CHANNELS)}) "
            f"and {N_SAMPLES} rows of samples"
        )
    try:
        rows = list(csv.reader(io.StringIO(text)))
    except csv.Error as exc:
        raise RecordFormatError(f"malformed CSV: {exc}") from exc
    while rows and not any(cell.strip() for cell in rows[-1]):
        rows.pop()  # trailing blank lines
    header = [cell.strip() for cell in rows[0]]
    if "" in header:
        raise RecordFormatError(f"malformed CSV: the header row {rows[0]!r} has an empty column name")
    unknown = [name for name in header if name not in CHANNELS]
    if unknown:
        if _is_number(unknown[0]):
            raise RecordFormatError(
                f"the CSV's first row {rows[0][:5]!r} is not a header; start with a row of channel names "
                f"({', '.join(CHANNELS)})"
            )
        raise RecordError(f"unknown channel {unknown[0]!r} in the CSV header; known channels: {', '.join(CHANNELS)}")
    if len(set(header)) != len(header):
        dup = next(name for name in header if header.count(name) > 1)
        raise RecordFormatError(f"channel {dup!r} appears twice in the CSV header")
    data = rows[1:]
    if len(data) != N_SAMPLES:
        raise RecordError(f"the CSV has {len(data)} data rows; a record needs exactly {N_SAMPLES} (one per sample)")
    columns: list[list[float]] = [[] for _ in header]
    for r, row in enumerate(data, start=2):
        if len(row) != len(header):
            raise RecordFormatError(f"malformed CSV: line {r} has {len(row)} fields, the header has {len(header)}")
        for j, cell in enumerate(row):
            try:
                columns[j].append(float(cell))
            except ValueError:
                raise RecordFormatError(
                    f"malformed CSV: line {r}, column {header[j]!r}: {cell!r} is not a number"
                ) from None
    return Record(
        channels={name: np.asarray(column, dtype=float) for name, column in zip(header, columns, strict=True)},
        sample_interval=sample_interval,
        event_index=event_index,
        conditions=dict(conditions or {}),
    )


def record_to_csv(record: Record) -> str:
    """The CSV form of a record (values written with full precision: they round-trip exactly)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    names = list(record.channels)
    writer.writerow(names)
    for row in zip(*(record.channels[n].tolist() for n in names), strict=True):
        writer.writerow([repr(v) for v in row])
    return buf.getvalue()


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


# -- JSON -------------------------------------------------------------------------


def _reject_constant(token: str) -> Any:
    raise RecordFormatError(f"the JSON holds {token}, which is not a number; every sample must be finite")


def record_from_json(text: str) -> Record:
    """Parse the JSON record format (NaN / Infinity tokens are rejected)."""
    try:
        data = json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise RecordFormatError(f"malformed JSON: {exc}") from exc
    if not isinstance(data, dict) or not isinstance(data.get("channels"), dict):
        raise RecordFormatError(
            "a JSON record must be an object with 'channels' (an object of channel name -> list of samples) "
            "and optionally 'sample_interval', 'event_index', 'conditions'"
        )
    try:
        return Record.from_dict(data)
    except RecordError:
        raise
    except (TypeError, ValueError) as exc:  # e.g. a sample that is a string
        raise RecordFormatError(f"the JSON is not a valid record: {exc}") from exc


def record_to_json(record: Record) -> str:
    return json.dumps(record.to_dict(), allow_nan=False)


# -- files ------------------------------------------------------------------------


def read_record(
    path: str | Path,
    sample_interval: float | None = None,
    event_index: int | None = None,
    conditions: Mapping[str, float] | None = None,
) -> Record:
    """Read a record file: ``.json`` (record format) or ``.csv`` (CSV form).

    ``sample_interval``, ``event_index`` and ``conditions`` complete a CSV file
    (defaults: MODEL.md's ``SAMPLE_INTERVAL`` and ``EVENT_INDEX``); for a JSON file they override its values
    when given.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise RecordFormatError(f"cannot read record file {path}: {exc.strerror or exc}") from exc
    if suffix == ".csv":
        return record_from_csv(
            text,
            SAMPLE_INTERVAL if sample_interval is None else sample_interval,
            EVENT_INDEX if event_index is None else event_index,
            conditions,
        )
    if suffix == ".json":
        record = record_from_json(text)
        if sample_interval is None and event_index is None and not conditions:
            return record
        return Record(
            channels=record.channels,
            sample_interval=record.sample_interval if sample_interval is None else sample_interval,
            event_index=record.event_index if event_index is None else event_index,
            conditions={**record.conditions, **dict(conditions or {})},
            event_time=record.event_time,
        )
    raise RecordFormatError(f"record file {path} must end in .json or .csv")


def write_record(record: Record, path: str | Path) -> None:
    """Write a record file, JSON or CSV by the extension (CSV drops sample_interval, event_index, conditions)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        text = record_to_csv(record)
    elif suffix == ".json":
        text = record_to_json(record)
    else:
        raise RecordFormatError(f"record file {path} must end in .json or .csv")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")


__all__ = [
    "RecordError",
    "RecordFormatError",
    "read_record",
    "record_from_csv",
    "record_from_json",
    "record_to_csv",
    "record_to_json",
    "write_record",
]
