"""A long capture as a CSV (issue 54): parsed a block at a time, read as its excerpt by the CLI and the service.

The CSV reader (app/records_io.py) must read no further than a block ahead of what the engine has taken,
answer the same whatever its block size (a fault, a blank row or the end of the data falling on a block's
edge), and a long record must come out of the CLI's and the service's reading as the excerpt of the same
record, its length as read stored with it.
"""

from __future__ import annotations

import io
import itertools
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

import app.records_io as records_io
from app.records_io import RecordFormatError, csv_body_lines, decode_csv_body, read_record, record_from_csv
from app.services.diagnosis_requests import DiagnosisRequest, n_samples, parse
from engine.records import RecordError, SampleGrid, record_from_data
from engine.records.streamed import HOLD_SAMPLES
from engine.simulation import PlantParameters, simulate


def test_the_csv_is_read_a_block_ahead_at_most(monkeypatch: pytest.MonkeyPatch) -> None:
    """An endless CSV: its first blocks come out having read one block of rows, not the rest."""
    monkeypatch.setattr(records_io, "CSV_BLOCK_ROWS", 100)
    read = 0

    def lines() -> Iterator[str]:
        nonlocal read
        yield "t,a1\n"
        for i in itertools.count():
            read += 1
            yield f"{i * 1e-4},{i}\n"

    header, blocks = records_io._csv_blocks(lines())
    first = list(itertools.islice(blocks, 3))
    assert header == ["t", "a1"] and [b.shape for b in first] == [(100, 2)] * 3
    assert read <= 3 * 100 + 1
    assert first[2][-1, 1] == 299.0


#: CSV texts whose faults, blank rows and ends fall on the edges of small blocks.
TRICKY = {
    "clean": "v2\n" + "1\n" * 12,
    "trailing blank rows": "v2,a1\n" + "1,2\n" * 9 + "\n \n , \n",
    "blank row inside": "v2\n" + "1\n" * 5 + "\n" + "1\n" * 5,
    "blank full-width row inside": "v2,a1\n" + "1,2\n" * 5 + " , \n" + "1,2\n" * 5,
    "blank full-width row at the end": "v2,a1\n" + "1,2\n" * 7 + " , \n",
    "bad cell late": "v2,a1\n" + "1,2\n" * 8 + "1,x\n" + "1,2\n" * 3,
    "bad cell first, one row": "v2\nx\n",
    "bad cell first, then a row": "v2\nx\n1\n",
    "two faults": "v2,a1\n" + "1,2\n" * 3 + "1\n" + "1,y\n" + "1,2\n",
    "ragged late": "v2\n" + "1\n" * 10 + "1,2\n",
    "one row": "v2\n1\n\n\n",
    "only time, bad row": "t\n1\n2\nz\n",
    "newline in a quoted cell": 'v2\n1\n1\n"1\n2"\n1\n',
    "bare carriage return": "v2\n1\n1\r2\n1\n",
}


def _outcome(text: str) -> str:
    try:
        record = record_from_csv(text, event_index=1, sample_interval=1e-3 / 2)
    except (RecordError, RecordFormatError) as exc:
        return f"{type(exc).__name__}: {exc}"
    return repr({c: x.tolist() for c, x in record.channels.items()})


@pytest.mark.parametrize("name", sorted(TRICKY))
def test_the_csv_answers_the_same_whatever_its_block_size(monkeypatch: pytest.MonkeyPatch, name: str) -> None:
    outcomes = {}
    for rows in (1, 2, 3, 5, 1 << 12):
        monkeypatch.setattr(records_io, "CSV_BLOCK_ROWS", rows)
        outcomes[rows] = _outcome(TRICKY[name])
    assert len(set(outcomes.values())) == 1, outcomes


#: A CSV file and the channels it holds.
LongCsv = tuple[Path, dict[str, np.ndarray]]


@pytest.fixture(scope="module")
def long_csv(tmp_path_factory: pytest.TempPathFactory) -> LongCsv:
    """100 000 rows of 0.1 ms (10 s), the test 4 s in, a time column, no event index: file and channels."""
    grid = SampleGrid.around_event(1e-4, 0.05, 0.3)
    sim = simulate(PlantParameters(K=0.0068), grid=grid)
    rng = np.random.default_rng(2)
    n, before = 100_000, 40_000
    channels = {}
    for c, x in sim.channels.items():
        y = np.concatenate([np.zeros(before), x, np.full(n - before - x.size, x[-1])])
        channels[c] = np.round(y + rng.standard_normal(n) * 1e-3 * np.std(x), 9)
    t = np.round(np.arange(n) * 1e-4, 9)
    buffer = io.StringIO()
    buffer.write("t," + ",".join(channels) + "\n")
    np.savetxt(buffer, np.column_stack([t, *channels.values()]), fmt="%.9g", delimiter=",")
    path = tmp_path_factory.mktemp("long") / "capture.csv"
    path.write_text(buffer.getvalue(), encoding="utf-8")
    return path, channels


def test_long_csv_is_read_as_the_excerpt_of_the_whole_record(long_csv: LongCsv) -> None:
    path, channels = long_csv
    table = np.loadtxt(path, delimiter=",", skiprows=1)
    whole = record_from_data({c: table[:, j + 1] for j, c in enumerate(channels)}, time=table[:, 0])
    cli = read_record(path)
    body = path.read_bytes()
    served = parse(DiagnosisRequest("csv", body, {}))
    assert served.record.n_samples == cli.n_samples < HOLD_SAMPLES < whole.n_samples
    for record in (cli, served.record):
        assert record.excerpt is not None and record.origin.n_samples == whole.n_samples
        assert record.origin.first + record.event_index == whole.event_index
        assert record.test_window()[1] == whole.test_window()[1]
        assert all(np.array_equal(record.test_window()[0][c], whole.test_window()[0][c]) for c in channels)
    assert n_samples(served.record) == 100_000  # what a stored record says of its length
    assert "".join(csv_body_lines(body)) == body.decode("utf-8")


def test_a_body_that_is_not_utf8_is_refused_at_once() -> None:
    body = b"\xef\xbb\xbfv2\n1\n2\n\xff\n" + b"1\n" * 10
    with pytest.raises(RecordFormatError) as whole:
        decode_csv_body(body)
    with pytest.raises(RecordFormatError) as lines:
        csv_body_lines(body)  # before any line is parsed
    assert str(lines.value) == str(whole.value) == "the CSV is not UTF-8 text (byte 7 is invalid)"
