"""Record text and files (app/records_io.py): JSON and CSV forms."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from app.records_io import (
    RecordFormatError,
    read_record,
    record_from_csv,
    record_from_json,
    record_to_csv,
    write_record,
)
from engine.constants import N_SAMPLES
from engine.records import Record, RecordError


def _record() -> Record:
    rng = np.random.default_rng(1)
    return Record(
        channels={"v2": rng.normal(size=N_SAMPLES), "a1": rng.normal(size=N_SAMPLES) * 1e-7},
        conditions={"c": 1.25},
        event_time=0.03,
    )


def test_csv_round_trip_is_exact() -> None:
    rec = _record()
    text = record_to_csv(rec)
    assert text.splitlines()[0] == "a1,v2"  # canonical channel order
    back = record_from_csv(text, 2e-4, 10, {"c": 1.25})
    for name in rec.channels:
        assert np.array_equal(back[name], rec[name])
    assert (back.sample_interval, back.event_index, back.conditions) == (2e-4, 10, {"c": 1.25})


def test_csv_tolerates_spaces_crlf_and_trailing_blank_lines() -> None:
    text = " v2 , a1 \r\n" + "".join(f"{i}, {-i}\r\n" for i in range(N_SAMPLES)) + "\r\n\r\n"
    rec = record_from_csv(text)
    assert rec["v2"][5] == 5.0 and rec["a1"][5] == -5.0


@pytest.mark.parametrize(
    ("text", "error", "message"),
    [
        ("", RecordFormatError, "the CSV is empty"),
        ("v2,\n" + "1,2\n" * N_SAMPLES, RecordFormatError, "empty column name"),
        ("v2\n" + "1\n" * 5, RecordError, "the CSV has 5 data rows"),
        ("torque\n" + "1\n" * N_SAMPLES, RecordError, "unknown channel 'torque'"),
        ("1.0\n" * N_SAMPLES, RecordFormatError, "is not a header"),
        ("v2\n" + "1\n" * (N_SAMPLES - 1) + "1,2\n", RecordFormatError, f"line {N_SAMPLES + 1} has 2 fields"),
        ("v2\n" + "inf\n" * N_SAMPLES, RecordError, "non-finite value"),
    ],
)
def test_csv_errors_say_what_to_fix(text: str, error: type[Exception], message: str) -> None:
    with pytest.raises(error, match=message):
        record_from_csv(text)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{", "malformed JSON"),
        ("[1, 2]", "must be an object with 'channels'"),
        ('{"channels": {"v2": [Infinity]}}', "the JSON holds Infinity"),
        ('{"channels": {"v2": ["a"]}}', "not a valid record"),
    ],
)
def test_json_errors_say_what_to_fix(text: str, message: str) -> None:
    with pytest.raises(RecordFormatError, match=message):
        record_from_json(text)


def test_files_by_extension(tmp_path: Path) -> None:
    rec = _record()
    for name in ("r.json", "r.csv"):
        write_record(rec, tmp_path / name)
    from_json = read_record(tmp_path / "r.json")
    assert from_json.conditions == {"c": 1.25} and from_json.event_time == 0.03
    assert np.array_equal(from_json["v2"], rec["v2"])
    from_csv = read_record(tmp_path / "r.csv", conditions={"c": 1.25})
    assert np.array_equal(from_csv["a1"], rec["a1"]) and from_csv.conditions == {"c": 1.25}
    overridden = read_record(tmp_path / "r.json", conditions={"J1": 0.8})
    assert overridden.conditions == {"c": 1.25, "J1": 0.8}
    with pytest.raises(RecordFormatError, match=r"must end in \.json or \.csv"):
        write_record(rec, tmp_path / "r.txt")
