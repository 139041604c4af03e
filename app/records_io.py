"""Records as text and files: the service's JSON record format and its CSV form.

JSON is :meth:`engine.records.Record.to_dict` / ``from_dict`` (``sample_interval``,
``event_index``, ``channels``, ``conditions``, and optionally ``units``, ``t``,
``event_time``). The CSV form has a header row of channel names (a non-empty
subset of ``a1, m_el, omega1, a2, v2``, and optionally a time column ``t`` in
seconds) and one row per sample, as many rows as the bench recorded; the
sample interval (when there is no ``t`` column), the event index (when the
event is not to be located from the data), the units and the conditions travel
beside it (query parameters over HTTP, options on the command line).

Whatever the form, the record is read by :func:`engine.records.record_from_data`,
the engine's one boundary for records as a bench gives them: units are
converted there, a ``t`` column defines the interval there, and a missing event
index is located there. A CSV is parsed a block of rows at a time and read by
that boundary's form for records given in pieces
(:func:`engine.records.streamed.record_from_chunks`), so that a long capture is
never held whole. This module only turns text into the arguments of those
calls (and records back into text).

The CSV form is a wire format of the service and the CLI (both in ``app``); the
engine only knows :class:`~engine.records.Record`, so the codec lives here.
"""

from __future__ import annotations

import codecs
import csv
import io
import itertools
import json
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from engine.constants import CHANNELS, POST_EVENT_TIME, PRE_EVENT_TIME
from engine.records import UNITS, Record, RecordError
from engine.records.streamed import Chunk, record_from_chunks
from engine.records.units import BASE_TORQUE, from_model_units

#: Name of the optional time column of the CSV form and the JSON format [s].
TIME_COLUMN = "t"


class RecordFormatError(ValueError):
    """Raised for text that is not a record in JSON or CSV form; the message says what to fix."""


# -- units as text ------------------------------------------------------------------

#: Accepted units per channel in words, for help texts (from the engine's one table, :data:`engine.records.UNITS`).
ACCEPTED_UNITS_DOC = "; ".join(
    f"{c}: " + ", ".join(f"{u} (needs conditions.{BASE_TORQUE})" if f is None else u for u, f in UNITS[c].items())
    for c in CHANNELS
)

#: How a set of units is written as one string (the ``units`` query parameter, the ``X-Units`` header).
UNITS_SYNTAX = "CHANNEL:UNIT pairs separated by commas, e.g. omega1:rpm,a1:g"


def parse_units(text: str | None) -> dict[str, str]:
    """Units written as ``CHANNEL:UNIT`` pairs separated by commas (e.g. ``omega1:rpm,a1:g``).

    Only the syntax is checked here; whether a channel may be given in a unit is the
    engine's to say (:data:`engine.records.UNITS`, checked when the record is read).

    Parameters
    ----------
    text : str or None
        The string; ``None`` or blank means no units (every channel in its model unit).

    Returns
    -------
    dict of str to str
        Channel -> unit.

    Raises
    ------
    RecordFormatError
        A pair without ``:``, an empty channel or unit, or a channel named twice.
    """
    units: dict[str, str] = {}
    if text is None or not text.strip():
        return units
    for pair in text.split(","):
        channel, sep, unit = pair.partition(":")
        channel, unit = channel.strip(), unit.strip()
        if not sep or not channel or not unit:
            raise RecordFormatError(f"units: {pair.strip()!r} is not CHANNEL:UNIT; write {UNITS_SYNTAX}")
        if channel in units:
            raise RecordFormatError(f"units: channel {channel!r} is given twice; write {UNITS_SYNTAX}")
        units[channel] = unit
    return units


def format_units(units: Mapping[str, str]) -> str:
    """The inverse of :func:`parse_units` (``""`` for no units)."""
    return ",".join(f"{c}:{u}" for c, u in units.items())


# -- CSV ------------------------------------------------------------------------


#: Rows of a CSV parsed at a time: about 2 MB of Python strings for five channels and a time column, then one
#: float64 block (larger blocks were no faster: 2.1 s for 10^6 rows at 4096, 2.3 s at 16 384).
CSV_BLOCK_ROWS = 1 << 12


def _csv_blocks(lines: Iterable[str]) -> tuple[list[str], Iterator[np.ndarray]]:
    """Header and numeric blocks of a CSV (``t`` included), read as the blocks are taken; raises on malformed CSV.

    The header is read at once (its faults raised here); the data rows are parsed :data:`CSV_BLOCK_ROWS` at
    a time into float64 blocks of shape ``(rows, columns)``, which the returned iterator yields as it
    reads on (the faults of the rows raised from it, the first one, as the whole text read at once would
    name it). Nothing longer than a block is held: a long record is never a list of millions of rows or
    numbers (whose garbage collection would hold the interpreter, and with it the service's event loop,
    for a noticeable time), and the loop lets other threads run between blocks.
    """
    first_lines: list[str] = []  # whitespace before the first text, read to tell an empty CSV
    stream = iter(lines)
    for line in stream:
        first_lines.append(line)
        if line.strip():
            break
    else:
        raise RecordFormatError(
            f"the CSV is empty; send a header row of channel names ({', '.join(CHANNELS)}, optionally "
            f"{TIME_COLUMN!r} for the time in s) and one row per sample"
        )
    reader = csv.reader(itertools.chain(first_lines, stream))
    try:
        header = _csv_header(next(reader))
    except csv.Error as exc:
        raise RecordFormatError(f"malformed CSV: {exc}") from exc
    return header, _CsvRows(header).blocks(reader)


class _CsvRows:
    """The data rows of a CSV, checked as the whole text read at once would check them.

    A data row is a row with a non-blank cell, or a blank one followed by such a row (blank rows at the end
    are ignored); each must have one number per header column. The first faulty row is reported once at
    least two data rows have been read (with fewer, the record is too short: that is reported instead).
    """

    def __init__(self, header: list[str]) -> None:
        self.header = header
        self.n_rows = 0
        self.blank: list[tuple[int, list[str]]] = []  # blank rows not yet known to lie inside the data
        self.failure: RecordFormatError | None = None

    def blocks(self, reader: Iterator[list[str]]) -> Iterator[np.ndarray]:
        line = 2  # the first data row's number (rows count as the csv module reads them)
        while True:
            try:
                rows = list(itertools.islice(reader, CSV_BLOCK_ROWS))
            except csv.Error as exc:  # the rows before it were read first (their fault would be reported)
                raise RecordFormatError(f"malformed CSV: {exc}") from exc
            if not rows:
                break
            block = self._block(line, rows)
            line += len(rows)
            if block.shape[0]:
                yield block
        if self.n_rows < 2:
            raise RecordError(
                f"the CSV has {self.n_rows} data row(s); a record needs one row per sample, covering at least "
                f"{PRE_EVENT_TIME * 1e3:g} ms before the event and {POST_EVENT_TIME * 1e3:g} ms from it on"
            )
        if self.failure is not None:
            raise self.failure

    def _block(self, line: int, rows: list[list[str]]) -> np.ndarray:
        """The numbers of ``rows`` (data rows ``line`` on): at once when every row is whole and numeric, else row
        by row (blank rows, a faulty row)."""
        width = len(self.header)
        if not self.blank and self.failure is None and all(len(row) == width for row in rows):
            try:
                block = np.array(rows, dtype=float)  # float() of each cell: the same numbers, the same refusals
            except ValueError:
                pass
            else:  # no blank row among them: a blank cell is no number
                self.n_rows += len(rows)
                return block.reshape(len(rows), width)
        numbers: list[list[float]] = []
        for r, row in enumerate(rows, start=line):
            if not any(cell.strip() for cell in row):
                self.blank.append((r, row))
                continue
            for at, cells in (*self.blank, (r, row)):
                self.n_rows += 1
                if self.failure is None:
                    self.failure = self._numbers(at, cells, numbers)
            self.blank.clear()
            if self.failure is not None and self.n_rows >= 2:
                raise self.failure
        return np.array(numbers, dtype=float).reshape(len(numbers), width)

    def _numbers(self, line: int, row: list[str], numbers: list[list[float]]) -> RecordFormatError | None:
        """Append the numbers of data row ``line`` to ``numbers``; the error (not raised) when the row is malformed."""
        if len(row) != len(self.header):
            return RecordFormatError(
                f"malformed CSV: line {line} has {len(row)} fields, the header has {len(self.header)}"
            )
        values = []
        for j, cell in enumerate(row):
            try:
                values.append(float(cell))
            except ValueError:
                return RecordFormatError(
                    f"malformed CSV: line {line}, column {self.header[j]!r}: {cell!r} is not a number"
                )
        numbers.append(values)
        return None


def _text_lines(text: str) -> Iterator[str]:
    """The lines of ``text``, each with its ``\\n`` (as :class:`io.StringIO` gives them), one at a time."""
    start = 0
    while start < len(text):
        end = text.find("\n", start)
        if end < 0:
            yield text[start:]
            return
        yield text[start : end + 1]
        start = end + 1


def _csv_header(row: list[str]) -> list[str]:
    """The CSV's header row, checked: channel names (and optionally ``t``), each once."""
    header = [cell.strip() for cell in row]
    if "" in header:
        raise RecordFormatError(f"malformed CSV: the header row {row!r} has an empty column name")
    unknown = [name for name in header if name not in CHANNELS and name != TIME_COLUMN]
    if unknown:
        if _is_number(unknown[0]):
            raise RecordFormatError(
                f"the CSV's first row {row[:5]!r} is not a header; start with a row of channel names "
                f"({', '.join(CHANNELS)}, optionally {TIME_COLUMN!r})"
            )
        raise RecordError(
            f"unknown channel {unknown[0]!r} in the CSV header; known channels: {', '.join(CHANNELS)} "
            f"(and {TIME_COLUMN!r}, the time in s)"
        )
    if len(set(header)) != len(header):
        dup = next(name for name in header if header.count(name) > 1)
        what = "column" if dup == TIME_COLUMN else "channel"
        raise RecordFormatError(f"{what} {dup!r} appears twice in the CSV header")
    return header


def decode_csv_body(raw: bytes) -> str:
    """A CSV request body as text (UTF-8, with or without a byte-order mark); ``RecordFormatError`` otherwise."""
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise RecordFormatError(f"the CSV is not UTF-8 text (byte {exc.start} is invalid)") from None


#: Bytes of a request body decoded at a time when it is checked.
_DECODE_BYTES = 1 << 20


def csv_body_lines(raw: bytes) -> Iterator[str]:
    """A CSV request body's lines, decoded as they are read (the lines :func:`decode_csv_body`'s text splits into).

    The body is first checked to be UTF-8 (with or without a byte-order mark) a megabyte at a time, so a
    body that is not is refused at once as :func:`decode_csv_body` refuses it; then its lines are decoded as
    the parser takes them: the body is never held a second time, as text.

    Raises
    ------
    RecordFormatError
        The body is not UTF-8 (the message names the first invalid byte).
    """
    decoder = codecs.getincrementaldecoder("utf-8-sig")()
    view = memoryview(raw)
    try:
        for start in range(0, len(raw), _DECODE_BYTES):
            decoder.decode(view[start : start + _DECODE_BYTES])
        decoder.decode(b"", final=True)
    except UnicodeDecodeError:
        decode_csv_body(raw)  # raises, naming the byte as the whole body decoded at once does
        raise
    return io.TextIOWrapper(io.BytesIO(raw), encoding="utf-8-sig", newline="\n")


def record_from_csv(
    text: str | Iterable[str],
    sample_interval: float | None = None,
    event_index: int | None = None,
    conditions: Mapping[str, float] | None = None,
    units: Mapping[str, str] | None = None,
    *,
    default_interval: float | None = None,
) -> Record:
    """Parse the CSV form of a record.

    The text is parsed a block of rows at a time and handed to the engine's boundary for records read
    in pieces (:func:`engine.records.streamed.record_from_chunks`): a record of more than
    :data:`~engine.records.streamed.HOLD_SAMPLES` rows is never held whole, only the stretch around its
    event that the analyses read (the returned record is then that excerpt: ``record.excerpt``), and
    it is not capped at :data:`~engine.records.limits.MAX_SAMPLES`.

    Parameters
    ----------
    text : str or iterable of str
        Header row of channel names (optionally ``t``, the time [s] of each sample), then
        one row per sample; any number of rows, the same for every column. A string, or its
        lines (an open text file).
    sample_interval : float, optional
        Ts [s] (10 us to 1 ms). Default: the step of the ``t`` column, or without one
        ``default_interval``; given together with ``t`` the two must agree.
    event_index : int, optional
        Index of the sample at the event t_e; omitted, the event is located from m_el or a1
        (the record's ``event_location`` says how).
    conditions : mapping of str to float, optional
        Known operating conditions (``K`` [m], ``J1`` [kg m^2], ``c`` [pu], ``c1`` [pu],
        ``base_torque`` [N*m] for an m_el in N*m).
    units : mapping of str to str, optional
        Unit per channel (:data:`engine.records.UNITS`); a channel not named is in its model unit.
    default_interval : float, optional
        Ts [s] of a CSV with neither ``sample_interval`` nor a ``t`` column: the drive's protocol interval
        when a drive is given (``DriveDescription.grid().sample_interval``), else MODEL.md's 0.1 ms.

    Returns
    -------
    Record
        In model units, remembering ``units``.

    Raises
    ------
    RecordFormatError
        Malformed CSV (no header, duplicate column, ragged rows, a field that is not a number).
    engine.records.RecordError
        Well-formed CSV that is not a valid record (unknown channel or unit, a time column
        that is not uniform or contradicts ``sample_interval``, NaN or inf, too little time
        around the event: :class:`~engine.records.ProtocolError` says how much is missing).
    """
    header, blocks = _csv_blocks(_text_lines(text) if isinstance(text, str) else text)
    columns = {name: j for j, name in enumerate(header) if name != TIME_COLUMN}
    if not columns:
        for _ in blocks:  # the rows' own faults are reported first
            pass
        raise RecordError(f"the CSV holds only the time column; add at least one channel ({', '.join(CHANNELS)})")
    at_time = header.index(TIME_COLUMN) if TIME_COLUMN in header else None
    chunks: Iterator[Chunk] = (
        ({name: block[:, j] for name, j in columns.items()}, None if at_time is None else block[:, at_time])
        for block in blocks
    )
    return record_from_chunks(
        chunks,
        sample_interval,
        event_index,
        dict(conditions or {}),
        dict(units or {}),
        default_interval=default_interval,
    )


def record_to_csv(record: Record, with_time: bool = False) -> str:
    """The CSV form of a record, the samples in the record's own units.

    Values are written with full precision: reading the text back with the same units
    gives the same model-unit samples (to the last bit for channels in their model unit).

    Parameters
    ----------
    record : Record
    with_time : bool
        Also write a first column ``t``: the time of each sample [s] counted from the
        first sample (``k * sample_interval``, so 0 at sample 0; not relative to the
        event), which carries the sample interval.

    Returns
    -------
    str
        Header row, then one row per sample.

    Notes
    -----
    The CSV form cannot carry the unit names, the event index, the conditions, t_e or the
    event location; without ``with_time`` it cannot carry the sample interval either. Give
    them beside the CSV when it is read (query parameters, command-line options).
    """
    values = from_model_units(record.channels, record.units, record.conditions)
    names = list(values)
    columns = [values[n].tolist() for n in names]
    if with_time:
        names = [TIME_COLUMN, *names]
        columns = [(np.arange(record.n_samples) * record.sample_interval).tolist(), *columns]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(names)
    for row in zip(*columns, strict=True):
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


def record_from_json(
    text: str,
    sample_interval: float | None = None,
    event_index: int | None = None,
    conditions: Mapping[str, float] | None = None,
    units: Mapping[str, str] | None = None,
    *,
    default_interval: float | None = None,
) -> Record:
    """Parse the JSON record format (NaN / Infinity tokens are rejected).

    Parameters
    ----------
    text : str
        A JSON object with ``channels`` and optionally ``sample_interval`` [s], ``event_index``
        (omitted: located), ``conditions``, ``units``, ``t`` [s] and ``event_time`` [s].
    sample_interval, event_index : optional
        Replace the record's values when given.
    conditions, units : mapping, optional
        Merged over the record's (a value given here wins).
    default_interval : float, optional
        Ts [s] of a record with neither ``sample_interval`` nor ``t``: the drive's protocol interval when a
        drive is given, else MODEL.md's 0.1 ms.

    Raises
    ------
    RecordFormatError
        Malformed JSON, or JSON that is not a record object.
    engine.records.RecordError
        A record the engine refuses (the message says what to fix).
    """
    try:
        data = json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise RecordFormatError(f"malformed JSON: {exc}") from exc
    if not isinstance(data, dict) or not isinstance(data.get("channels"), dict):
        raise RecordFormatError(
            "a JSON record must be an object with 'channels' (an object of channel name -> list of samples) "
            "and optionally 'sample_interval', 'event_index', 'conditions', 'units', 't', 'event_time'"
        )
    for key in ("conditions", "units"):
        if data.get(key) is not None and not isinstance(data[key], dict):
            raise RecordFormatError(f"the JSON record's {key!r} must be an object")
    if sample_interval is not None:
        data["sample_interval"] = sample_interval
    if event_index is not None:
        data["event_index"] = event_index
    if conditions:
        data["conditions"] = {**(data.get("conditions") or {}), **dict(conditions)}
    if units:
        data["units"] = {**(data.get("units") or {}), **dict(units)}
    try:
        return Record.from_dict(data, default_interval=default_interval)
    except RecordError:
        raise
    except (TypeError, ValueError) as exc:  # e.g. a sample that is a string
        raise RecordFormatError(f"the JSON is not a valid record: {exc}") from exc


def record_to_json(record: Record) -> str:
    """The JSON record format (:meth:`Record.to_dict`: samples in the record's own units)."""
    return json.dumps(record.to_dict(), allow_nan=False)


# -- files ------------------------------------------------------------------------


def read_record(
    path: str | Path,
    sample_interval: float | None = None,
    event_index: int | None = None,
    conditions: Mapping[str, float] | None = None,
    units: Mapping[str, str] | None = None,
    *,
    default_interval: float | None = None,
) -> Record:
    """Read a record file: ``.json`` (record format) or ``.csv`` (CSV form).

    ``sample_interval`` [s], ``event_index``, ``conditions`` and ``units`` complete a CSV
    file (see :func:`record_from_csv`: without them Ts comes from its ``t`` column or is
    ``default_interval`` [s], and the event is located); for a JSON file they override its values when given
    (see :func:`record_from_json`). ``default_interval``: the Ts [s] of a record (CSV or JSON) that gives
    neither ``sample_interval`` nor ``t``, the drive's protocol interval when a drive is given; default
    MODEL.md's 0.1 ms.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".json"):
        raise RecordFormatError(f"record file {path} must end in .json or .csv")
    try:
        if suffix == ".csv":  # read as it is parsed (a long one is never held whole: record_from_csv)
            with path.open(encoding="utf-8-sig") as lines:
                return record_from_csv(
                    lines, sample_interval, event_index, conditions, units, default_interval=default_interval
                )
        text = path.read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise RecordFormatError(f"cannot read record file {path}: {exc.strerror or exc}") from exc
    return record_from_json(text, sample_interval, event_index, conditions, units, default_interval=default_interval)


def stated_provenance(path: str | Path) -> dict[str, Any] | None:
    """The drive a JSON record file states it was made on (``{"fingerprint": ..., "description": ...}``), or None.

    A simulated record carries ``drive`` as ``backlash simulate --drive`` and ``POST /v1/simulate`` write it; a CSV
    file, a record without it, or a file that does not parse (the record reader says what is wrong with it) states
    none.
    """
    path = Path(path)
    if path.suffix.lower() != ".json":
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8-sig"))
    except (OSError, ValueError):
        return None
    drive = data.get("drive") if isinstance(data, dict) else None
    if isinstance(drive, dict) and isinstance(drive.get("fingerprint"), str):
        return drive
    return None


def write_record(record: Record, path: str | Path, with_time: bool = False) -> None:
    """Write a record file, JSON or CSV by the extension.

    JSON keeps everything (:meth:`Record.to_dict`). CSV (:func:`record_to_csv`) keeps the
    samples in the record's units but loses the unit names, the event index, the conditions,
    t_e and the event location, and (unless ``with_time`` writes a ``t`` column) the sample
    interval: give them as options when reading it back.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        text = record_to_csv(record, with_time=with_time)
    elif suffix == ".json":
        text = record_to_json(record)
    else:
        raise RecordFormatError(f"record file {path} must end in .json or .csv")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")


__all__ = [
    "ACCEPTED_UNITS_DOC",
    "TIME_COLUMN",
    "UNITS_SYNTAX",
    "RecordError",
    "RecordFormatError",
    "csv_body_lines",
    "format_units",
    "parse_units",
    "read_record",
    "record_from_csv",
    "record_from_json",
    "record_to_csv",
    "record_to_json",
    "write_record",
]
