"""Record text and files (app/records_io.py): JSON and CSV forms, records as a bench gives them."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from app.records_io import (
    RecordFormatError,
    format_units,
    parse_units,
    read_record,
    record_from_csv,
    record_from_json,
    record_to_csv,
    record_to_json,
    write_record,
)
from app.schemas.common import RecordIn
from engine.constants import EVENT_INDEX, N_SAMPLES
from engine.records import ProtocolError, Record, RecordError, SampleGrid
from engine.simulation import PlantParameters, simulate

#: A bench's grid: 20 kHz, 10 ms before the event, 300 ms after it.
BENCH_GRID = SampleGrid.around_event(5e-5, 0.01, 0.3)
BENCH_UNITS = {"omega1": "rpm", "a1": "g"}
RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)


def _record() -> Record:
    rng = np.random.default_rng(1)
    return Record(
        channels={"v2": rng.normal(size=N_SAMPLES), "a1": rng.normal(size=N_SAMPLES) * 1e-7},
        conditions={"c": 1.25},
        event_time=0.03,
    )


@pytest.fixture(scope="module")
def bench() -> Record:
    """A simulated record on BENCH_GRID (model units), all five channels."""
    return simulate(PlantParameters(K=0.005), grid=BENCH_GRID)


def _model_values_equal(a: Record, b: Record, rtol: float = 1e-12) -> None:
    assert list(a.channels) == list(b.channels)
    for name in a.channels:
        np.testing.assert_allclose(a[name], b[name], rtol=rtol, atol=1e-12 * float(np.max(np.abs(b[name])) + 1))


def test_csv_round_trip_is_exact() -> None:
    rec = _record()
    text = record_to_csv(rec)
    assert text.splitlines()[0] == "a1,v2"  # canonical channel order
    back = record_from_csv(text, 2e-4, 30, {"c": 1.25})
    for name in rec.channels:
        assert np.array_equal(back[name], rec[name])
    assert (back.sample_interval, back.event_index, back.conditions) == (2e-4, 30, {"c": 1.25})
    assert back.event_location is None  # event_index was given


def test_csv_tolerates_spaces_crlf_and_trailing_blank_lines() -> None:
    text = " v2 , a1 \r\n" + "".join(f"{i}, {-i}\r\n" for i in range(N_SAMPLES)) + "\r\n\r\n"
    rec = record_from_csv(text, event_index=EVENT_INDEX)
    assert rec["v2"][5] == 5.0 and rec["a1"][5] == -5.0


@pytest.mark.parametrize(
    ("text", "error", "message"),
    [
        ("", RecordFormatError, "the CSV is empty"),
        ("v2,\n" + "1,2\n" * N_SAMPLES, RecordFormatError, "empty column name"),
        ("v2\n1\n", RecordError, "the CSV has 1 data row(s)"),
        ("torque\n" + "1\n" * N_SAMPLES, RecordError, "unknown channel 'torque'"),
        ("1.0\n" * N_SAMPLES, RecordFormatError, "is not a header"),
        ("v2\n" + "1\n" * (N_SAMPLES - 1) + "1,2\n", RecordFormatError, f"line {N_SAMPLES + 1} has 2 fields"),
        ("v2\n" + "inf\n" * N_SAMPLES, RecordError, "non-finite value"),
        ("t,v2,t\n" + "1,1,1\n" * N_SAMPLES, RecordFormatError, "column 't' appears twice"),
        ("t\n" + "1\n" * N_SAMPLES, RecordError, "only the time column"),
        # no event_index and neither m_el nor a1 to locate the event from
        ("v2\n" + "1\n" * N_SAMPLES, ProtocolError, "give event_index"),
    ],
)
def test_csv_errors_say_what_to_fix(text: str, error: type[Exception], message: str) -> None:
    with pytest.raises(error, match=message.replace("(", r"\(").replace(")", r"\)")):
        record_from_csv(text)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{", "malformed JSON"),
        ("[1, 2]", "must be an object with 'channels'"),
        ('{"channels": {"v2": [Infinity]}}', "the JSON holds Infinity"),
        ('{"channels": {"v2": [1, 2]}, "units": "rpm"}', "'units' must be an object"),
    ],
)
def test_json_errors_say_what_to_fix(text: str, message: str) -> None:
    with pytest.raises(RecordFormatError, match=message):
        record_from_json(text)


def test_json_samples_that_are_not_numbers_are_a_record_error() -> None:
    # was RecordFormatError "not a valid record"; the engine's boundary now says it
    with pytest.raises(RecordError, match="channel 'v2' must be a list of numbers"):
        record_from_json('{"channels": {"v2": ["a", "b"]}, "event_index": 0}')


def test_files_by_extension(tmp_path: Path) -> None:
    rec = _record()
    for name in ("r.json", "r.csv"):
        write_record(rec, tmp_path / name)
    from_json = read_record(tmp_path / "r.json")
    assert from_json.conditions == {"c": 1.25} and from_json.event_time == 0.03
    assert np.array_equal(from_json["v2"], rec["v2"])
    from_csv = read_record(tmp_path / "r.csv", event_index=EVENT_INDEX, conditions={"c": 1.25})
    assert np.array_equal(from_csv["a1"], rec["a1"]) and from_csv.conditions == {"c": 1.25}
    overridden = read_record(tmp_path / "r.json", conditions={"J1": 0.8})
    assert overridden.conditions == {"c": 1.25, "J1": 0.8}
    with pytest.raises(RecordFormatError, match=r"must end in \.json or \.csv"):
        write_record(rec, tmp_path / "r.txt")


# -- records as a bench gives them ---------------------------------------------------


def test_20_khz_csv_with_time_in_rpm_and_g_reads_as_the_json(bench: Record) -> None:
    in_units = bench.replace(units=BENCH_UNITS)
    text = record_to_csv(in_units, with_time=True)
    lines = text.splitlines()
    assert lines[0] == "t,a1,m_el,omega1,a2,v2" and len(lines) == BENCH_GRID.n_samples + 1
    first = [float(v) for v in lines[1].split(",")]
    assert first[0] == 0.0 and float(lines[2].split(",")[0]) == pytest.approx(5e-5, rel=1e-12)
    # the samples are written in rpm and g, not rad/s and m/s^2
    assert first[3] == pytest.approx(bench["omega1"][0] * RPM_PER_RAD_S, rel=1e-12)
    assert first[1] == pytest.approx(bench["a1"][0] / 9.80665, rel=1e-12)

    from_csv = record_from_csv(text, event_index=BENCH_GRID.event_index, units=BENCH_UNITS)
    from_json = record_from_json(record_to_json(in_units))
    assert from_json.units == BENCH_UNITS and json.loads(record_to_json(in_units))["units"] == BENCH_UNITS
    assert from_csv.sample_interval == pytest.approx(5e-5, rel=1e-9)  # from the t column
    assert (from_csv.n_samples, from_csv.event_index) == (BENCH_GRID.n_samples, BENCH_GRID.event_index)
    _model_values_equal(from_csv, from_json)
    _model_values_equal(from_csv, bench)  # back in rad/s and m/s^2
    assert from_csv.units == BENCH_UNITS


def test_event_index_omitted_is_located_at_the_rendered_sample(bench: Record) -> None:
    text = record_to_csv(bench.replace(units=BENCH_UNITS), with_time=True)
    located = record_from_csv(text, units=BENCH_UNITS)
    assert located.event_location is not None
    assert located.event_index == located.event_location.index == BENCH_GRID.event_index
    assert located.event_location.channel == "m_el"
    # the same through the JSON body model of the service
    data = bench.to_dict()
    del data["event_index"]
    via_schema = RecordIn.model_validate(data).to_record()
    assert via_schema.event_location is not None and via_schema.event_index == BENCH_GRID.event_index
    assert via_schema.to_dict()["event_location"]["index"] == BENCH_GRID.event_index


def test_unknown_unit_names_the_accepted_ones(bench: Record) -> None:
    with pytest.raises(RecordError, match=r"unknown unit 'rpmm' for channel 'omega1'; accepted units: rad/s, rpm, pu"):
        record_from_csv(record_to_csv(bench), event_index=BENCH_GRID.event_index, units={"omega1": "rpmm"})


def test_too_short_says_how_many_ms_are_missing(bench: Record) -> None:
    text = "\n".join(record_to_csv(bench, with_time=True).splitlines()[: 1 + BENCH_GRID.event_index + 3900]) + "\n"
    with pytest.raises(ProtocolError, match=r"5 ms after it missing"):  # 3900 samples of 50 us = 195 ms
        record_from_csv(text, event_index=BENCH_GRID.event_index)


def test_time_column_contradicting_the_sample_interval(bench: Record) -> None:
    text = record_to_csv(bench, with_time=True)
    with pytest.raises(RecordError, match=r"sample_interval 0.0001 s contradicts the time column 't'"):
        record_from_csv(text, sample_interval=1e-4, event_index=BENCH_GRID.event_index)
    data = {**bench.to_dict(), "t": (np.arange(bench.n_samples) * 1e-4).tolist(), "sample_interval": 5e-5}
    with pytest.raises(RecordError, match="contradicts the time column"):
        RecordIn.model_validate(data).to_record()


def test_json_file_options_override_and_merge(tmp_path: Path, bench: Record) -> None:
    path = tmp_path / "r.json"
    data = bench.to_dict()
    data["channels"]["omega1"] = (np.asarray(data["channels"]["omega1"]) * RPM_PER_RAD_S).tolist()
    del data["event_index"]
    path.write_text(json.dumps(data))
    rec = read_record(path, event_index=BENCH_GRID.event_index + 1, units={"omega1": "rpm"}, conditions={"c": 1.1})
    assert rec.event_index == BENCH_GRID.event_index + 1 and rec.event_location is None
    assert rec.units == {"omega1": "rpm"} and rec.conditions["c"] == 1.1 and rec.conditions["K"] == 0.005
    np.testing.assert_allclose(rec["omega1"], bench["omega1"], rtol=1e-12)


def test_csv_file_in_other_units_keeps_them_on_the_way_out(tmp_path: Path, bench: Record) -> None:
    rec = bench.replace(units={"v2": "mm/s"})
    write_record(rec, tmp_path / "r.csv")
    lines = (tmp_path / "r.csv").read_text().splitlines()
    assert lines[0] == "a1,m_el,omega1,a2,v2"  # no t column unless asked for
    k = BENCH_GRID.event_index + 1000
    assert bench["v2"][k] != 0.0 and float(lines[1 + k].split(",")[4]) == pytest.approx(bench["v2"][k] * 1e3, rel=1e-12)
    back = read_record(
        tmp_path / "r.csv", sample_interval=5e-5, event_index=BENCH_GRID.event_index, units={"v2": "mm/s"}
    )
    _model_values_equal(back, bench)


def test_units_text_syntax() -> None:
    assert parse_units("omega1:rpm, a1:g") == {"omega1": "rpm", "a1": "g"}
    assert parse_units(None) == parse_units("  ") == {}
    assert parse_units(format_units({"m_el": "N*m", "a2": "m/s^2"})) == {"m_el": "N*m", "a2": "m/s^2"}
    malformed = [("omega1=rpm", "is not CHANNEL:UNIT"), ("omega1:", "is not CHANNEL:UNIT"), ("a1:g,a1:g", "twice")]
    for bad, message in malformed:
        with pytest.raises(RecordFormatError, match=message):
            parse_units(bad)
