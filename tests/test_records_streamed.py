"""A record read in pieces (issue 54, memory bounded by the test window): engine.records.streamed and its parts.

A long record is checked, located and cut as it is read, and only its excerpt around the event is kept;
every figure an analysis draws from the excerpt must be the one it draws from the whole record, every
refusal the one the whole record gets, and reading it must not hold it.
"""

from __future__ import annotations

import math
import tracemalloc
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from engine.diagnosis.plausibility import TIME_FACTORS, check_record
from engine.records import (
    Excerpt,
    ProtocolError,
    RecordError,
    SampleGrid,
    locate_event,
    record_from_chunks,
    record_from_data,
    to_protocol_grid,
)
from engine.records.order import median, order_statistic
from engine.records.resample import reach
from engine.records.series import PIECE
from engine.records.spill import Spill
from engine.records.streamed import HOLD_SAMPLES, MARGIN_SAMPLES, READ_SPAN, Chunk
from engine.records.time_column import TimeSteps
from engine.simulation import PlantParameters, simulate

# -- the exact median in pieces ------------------------------------------------------------------


def _pieces(x: np.ndarray, size: int) -> Callable[[], Iterator[np.ndarray]]:
    return lambda: (x[i : i + size] for i in range(0, x.size, size))


@pytest.mark.parametrize("n", [1, 2, 3, 4, 7, 100, 1001, 4096])
def test_median_in_pieces_is_numpys_to_the_bit(n: int) -> None:
    rng = np.random.default_rng(n)
    for x in (
        rng.standard_normal(n),
        np.abs(rng.standard_normal(n)) * 1e-7,
        np.round(rng.standard_normal(n), 1),  # ties
        rng.integers(-2, 3, n).astype(float),
        np.zeros(n),
        rng.standard_normal(n) * 1e300,
    ):
        assert median(_pieces(x, 7), n) == float(np.median(x))
    x = rng.standard_normal(n)
    assert order_statistic(_pieces(x, 5), n - 1) == x.max()
    assert order_statistic(_pieces(x, 5), 0) == x.min()


# -- the event located in pieces -----------------------------------------------------------------


def _located_whole(channels: dict[str, np.ndarray], ts: float) -> int | None:
    """The locator as it read a record held whole before issue 54 (engine/records/event.py at b3c27be)."""

    def noise(x: np.ndarray) -> float:
        d2 = np.diff(x, 2)
        return float(np.median(np.abs(d2)) / 0.6744897501960817 / math.sqrt(6.0)) if d2.size else 0.0

    if "m_el" in channels:
        x = channels["m_el"]
        tail = max(3, min(x.size // 2, math.ceil(0.1 / ts - 1e-9)))
        dev = np.abs(x - float(np.median(x[-tail:])))
        above = np.flatnonzero(dev > max(6.0 * noise(x), 0.02 * float(np.max(dev))))
        if above.size and above[-1] + 1 < x.size and above[-1] + 1 > 0:
            return int(above[-1] + 1)
    if "a1" in channels:
        x = channels["a1"]
        sigma, quiet = noise(x), max(3, math.ceil(1e-3 / ts - 1e-9))
        d = np.abs(np.diff(x))
        thr = max(8.0 * sigma, 0.05 * float(np.max(d)))
        for k in np.flatnonzero(d > thr) + 1:
            stretch = x[k : k + quiet]
            if stretch.size < quiet:
                break
            if np.max(np.abs(stretch - stretch.mean())) <= 4.0 * sigma + 0.1 * d[k - 1]:
                return int(k)
    return None


def _capture(n: int, before: int, ts: float = 1e-4, noise: float = 1e-3, seed: int = 0) -> dict[str, np.ndarray]:
    """A long capture: at rest (zeros) for ``before`` samples, one simulated test, then its last sample held."""
    grid = SampleGrid.around_event(ts, 0.05, 0.3)
    sim = simulate(PlantParameters(K=0.0068), grid=grid)
    rng = np.random.default_rng(seed)
    out = {}
    for c, x in sim.channels.items():
        y = np.concatenate([np.zeros(before), x, np.full(n - before - x.size, x[-1])])
        out[c] = y + rng.standard_normal(n) * noise * (np.std(x) + 1e-12)
    return out


@pytest.mark.parametrize("channels", [("m_el",), ("a1",), ("a1", "m_el")])
@pytest.mark.parametrize("before", [3 * PIECE - 480, 100_000])  # the event (and a1's quiet stretch) across a piece
def test_event_located_in_pieces_where_the_whole_record_locates_it(channels: tuple[str, ...], before: int) -> None:
    ts = 1e-4
    rec = {c: x for c, x in _capture(260_000, before).items() if c in channels}
    assert rec[channels[0]].size > 3 * PIECE
    expected = _located_whole(rec, ts)
    assert expected is not None
    assert locate_event(rec, ts).index == expected
    with Spill(list(rec)) as spill:
        for i in range(0, 260_000, 9_999):
            spill.append({c: x[i : i + 9_999] for c, x in rec.items()})
        assert locate_event(spill.columns, ts).index == expected


# -- the time column in pieces -------------------------------------------------------------------


def _time_steps(t: np.ndarray, size: int) -> TimeSteps:
    steps = TimeSteps()
    for i in range(0, t.size, size):
        steps.add(t[i : i + size])
    return steps


@pytest.mark.parametrize("fault", [None, "jitter", "backwards", "nan", "two worst"])
def test_time_column_in_pieces_is_read_as_whole(fault: str | None) -> None:
    from engine.records import interval_from_time

    t = np.arange(50_000) * 1e-4 + 3.0
    if fault == "jitter":
        t[31_337] += 2e-6
    elif fault == "backwards":
        t[40_001] = t[40_000]
    elif fault == "nan":
        t[45_000] = np.nan
    elif fault == "two worst":  # the same largest deviation twice: the first one is named
        t[20_000] += 3e-6
        t[30_000] += 3e-6
    steps = _time_steps(t, 999)
    if fault is None:
        assert steps.interval(again=lambda: (t[i : i + 999] for i in range(0, t.size, 999))) == interval_from_time(t)
        return
    with pytest.raises(RecordError) as whole:
        interval_from_time(t)
    with pytest.raises(RecordError) as pieces:
        steps.interval(again=lambda: (t[i : i + 999] for i in range(0, t.size, 999)))
    assert str(pieces.value) == str(whole.value)


# -- a long record read in pieces ----------------------------------------------------------------


def _chunks(channels: dict[str, np.ndarray], time: np.ndarray | None, size: int = 4096) -> Iterator[Chunk]:
    n = next(iter(channels.values())).size
    for i in range(0, n, size):
        yield {c: x[i : i + size] for c, x in channels.items()}, None if time is None else time[i : i + size]


#: A capture's channels, its time column [s] and its sample interval [s].
Capture = tuple[dict[str, np.ndarray], np.ndarray, float]


@pytest.fixture(scope="module")
def long_capture() -> Capture:
    """150 000 samples of 50 us (7.5 s; the test 1.5 s in), a time column, no event index."""
    ts = 5e-5
    channels = _capture(150_000, 30_000, ts=ts, seed=3)
    return channels, 10.0 + np.arange(150_000) * ts, ts


def test_long_record_is_its_excerpt_and_answers_as_the_whole(long_capture: Capture) -> None:
    channels, t, ts = long_capture
    whole = record_from_data(channels, time=t, units={}, conditions={"c1": 0.2})
    part = record_from_chunks(_chunks(channels, t), conditions={"c1": 0.2})
    assert whole.excerpt is None and part.excerpt is not None
    assert part.origin.n_samples == whole.n_samples == 150_000
    assert part.n_samples < 2 * READ_SPAN * SampleGrid.protocol(ts).n_samples + 2 * MARGIN_SAMPLES
    assert part.sample_interval == whole.sample_interval
    assert part.event_location == whole.event_location
    assert part.origin.first + part.event_index == whole.event_index
    (w_whole, use_whole), (w_part, use_part) = whole.test_window(), part.test_window()
    assert use_part == use_whole
    for c in whole.channels:
        assert np.array_equal(w_part[c], w_whole[c])
    assert w_part.origin == Excerpt(use_whole.first, 150_000)
    resampled_whole, resampled_part = to_protocol_grid(whole), to_protocol_grid(part)
    for c in whole.channels:
        assert np.array_equal(resampled_part[c], resampled_whole[c])
    assert [w.to_dict() for w in check_record(part)] == [w.to_dict() for w in check_record(whole)]


def test_excerpt_covers_every_reading_of_the_analyses() -> None:
    """The excerpt holds what the plausibility checks (a tenth of the interval) and the resampler read."""
    assert min(TIME_FACTORS) >= 1.0 / READ_SPAN
    for ts in (1e-5, 1.3e-5, 2.5e-5, 3e-5, 7e-5, 1e-4, 3.3e-4, 1e-3):
        assert reach(ts) <= MARGIN_SAMPLES


@pytest.mark.parametrize("hold", [None, 5_000])
def test_a_record_read_in_pieces_without_interval_or_time_is_read_at_the_default(hold: int | None) -> None:
    """Held whole or read as a long record: without ``sample_interval`` or a time column, ``default_interval``
    (a drive's protocol interval) is the record's interval, MODEL.md's 0.1 ms without it; a given one wins."""
    channels = {"v2": np.zeros(12_000)}
    for default, given, expected in ((2e-4, None, 2e-4), (None, None, 1e-4), (2e-4, 5e-5, 5e-5)):
        record = record_from_chunks(_chunks(channels, None), given, 96, hold=hold, default_interval=default)
        assert record.sample_interval == expected
        assert (record.excerpt is not None) == (hold is not None)


def test_short_record_read_in_pieces_is_held_whole(long_capture: Capture) -> None:
    channels, t, _ = long_capture
    short = {c: x[25_000 : 25_000 + HOLD_SAMPLES] for c, x in channels.items()}
    whole = record_from_data(short, time=t[25_000 : 25_000 + HOLD_SAMPLES])
    read = record_from_chunks(_chunks(short, t[25_000 : 25_000 + HOLD_SAMPLES]))
    assert read.excerpt is None and read.n_samples == HOLD_SAMPLES and read.event_index == whole.event_index
    assert all(np.array_equal(read[c], whole[c]) for c in whole.channels)


@pytest.mark.parametrize(
    "fault",
    [
        "nan late",
        "huge late",
        "huge in g",
        "time jitter late",
        "unknown unit",
        "too short after",
        "event index 2.5",
        "interval contradicts",
        "torque without its base",
    ],
)
def test_long_record_is_refused_as_the_whole_one(long_capture: Capture, fault: str) -> None:
    channels, t, _ = long_capture
    channels = {c: x.copy() for c, x in channels.items()}
    t = t.copy()
    kwargs: dict = {"units": {}, "conditions": {}}
    if fault == "nan late":
        channels["a2"][140_000] = np.nan
    elif fault == "huge late":
        channels["omega1"][120_000] = 2e12
    elif fault == "huge in g":
        channels["a1"][110_000] = 5e11
        kwargs["units"] = {"a1": "g"}
    elif fault == "time jitter late":
        t[149_000] += 1e-6
    elif fault == "unknown unit":
        kwargs["units"] = {"v2": "furlong/s"}
    elif fault == "too short after":
        channels = {c: x[:34_000] for c, x in channels.items()}
        t = t[:34_000]
    elif fault == "event index 2.5":
        kwargs["event_index"] = 2.5
    elif fault == "interval contradicts":
        kwargs["sample_interval"] = 1e-4
    elif fault == "torque without its base":
        kwargs["units"] = {"m_el": "N*m"}
    with pytest.raises(RecordError) as whole:
        record_from_data(channels, time=t, **kwargs)
    with pytest.raises(RecordError) as part:
        record_from_chunks(_chunks(channels, t, 5_000), hold=20_000, **kwargs)
    assert type(part.value) is type(whole.value)
    assert str(part.value) == str(whole.value)
    if fault == "too short after":
        assert isinstance(part.value, ProtocolError)


def test_reading_a_long_record_holds_its_excerpt_not_the_record() -> None:
    """Issue 54: memory bounded by the test window, not by the record's length.

    4 million samples of 0.1 ms (400 s; five channels and a time column: 192 MB as float64, 32 MB per
    column), given a chunk of 4096 samples at a time as the CSV reader gives them. What reading holds at its
    peak is the chunks held before the record is known to be long (HOLD_SAMPLES: 3.1 MB), a chunk, the
    excerpt (20 736 samples: 1 MB) and the locator's pieces (PIECE samples: 0.5 MB each, a few at once):
    5.1 MB measured (tracemalloc, numpy 2, 2026-11). The bound, 16 MB, is three times that and half of one
    column of the record: any copy of a whole column (or the record held whole, 192 MB) fails it. Nothing
    is timed.
    """
    ts, n, before = 1e-4, 4_000_000, 1_000_000
    grid = SampleGrid.around_event(ts, 0.05, 0.5)
    sim = simulate(PlantParameters(K=0.0068), grid=grid)
    core = np.stack(list(sim.channels.values()), axis=1)
    rng = np.random.default_rng(7)

    def chunks() -> Iterator[Chunk]:
        for i in range(0, n, 4096):
            rows = np.arange(i, min(i + 4096, n))
            j = np.clip(rows - before, 0, core.shape[0] - 1)
            block = np.where((rows < before)[:, None], 0.0, core[j]) + rng.standard_normal((rows.size, 5)) * 1e-3
            yield dict(zip(sim.channels, block.T, strict=True)), rows * ts

    tracemalloc.start()
    try:
        record = record_from_chunks(chunks())
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert record.origin == Excerpt(before + grid.event_index - record.event_index, n)
    assert record.event_location is not None and record.event_location.index == before + grid.event_index
    assert record.n_samples * 8 * 5 < 2e6
    assert peak < 16e6, f"reading a record of {n} samples peaked at {peak / 1e6:.1f} MB"
