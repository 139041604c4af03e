"""The record boundary (engine.records): grids, units, time columns, event location, resampling."""

from __future__ import annotations

import math

import numpy as np
import pytest

from engine.constants import CHANNELS, EVENT_INDEX, N_SAMPLES, OMEGA_B, POST_EVENT_TIME, PRE_EVENT_TIME
from engine.records import (
    PROTOCOL_GRID,
    ProtocolError,
    Record,
    RecordError,
    SampleGrid,
    locate_event,
    record_from_data,
    resample_to_grid,
    to_protocol_grid,
)
from engine.records.units import STANDARD_GRAVITY, factor
from engine.simulation import PlantParameters, add_white_noise, simulate

# -- grids -------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("ts", "n_before", "n_after"),
    [
        (1e-4, 48, 2000),
        (2.5e-5, 192, 8000),
        (5e-5, 96, 4000),
        (2e-4, 24, 1000),
        (5e-4, 10, 400),
        (1e-3, 5, 200),
        (3e-4, 16, 667),
    ],
)
def test_protocol_grid_covers_the_test_window_with_the_fewest_samples(ts: float, n_before: int, n_after: int) -> None:
    g = SampleGrid.protocol(ts)
    assert (g.event_index, g.n_samples - g.event_index) == (n_before, n_after)
    before, after = g.covered
    assert before >= PRE_EVENT_TIME - 1e-12 and after >= POST_EVENT_TIME - 1e-12
    shorter = SampleGrid(ts, g.n_samples - 1, g.event_index)
    assert shorter.missing()[1] > 0


def test_model_grid_is_the_protocol_grid_at_0_1_ms() -> None:
    assert SampleGrid.protocol(1e-4) == PROTOCOL_GRID
    assert (PROTOCOL_GRID.n_samples, PROTOCOL_GRID.event_index) == (N_SAMPLES, EVENT_INDEX)


@pytest.mark.parametrize(("ts", "ok"), [(1e-5, True), (9e-6, False), (1e-3, True), (1.1e-3, False)])
def test_sample_interval_range(ts: float, ok: bool) -> None:
    g = SampleGrid.protocol(min(max(ts, 1e-5), 1e-3))
    chans = {"a1": np.zeros(g.n_samples)}
    if ok:
        Record(chans, ts, g.event_index)
    else:
        with pytest.raises(ProtocolError, match="outside the accepted range"):
            Record(chans, ts, g.event_index)


def test_too_short_record_says_how_much_is_missing() -> None:
    with pytest.raises(ProtocolError, match=r"4\.8 ms after it missing"):
        Record({"a1": np.zeros(2000)})
    with pytest.raises(ProtocolError, match=r"2 ms before the event missing"):
        Record({"a1": np.zeros(2048)}, 1e-4, 28)


def test_longer_record_window_is_the_test_window() -> None:
    x = np.arange(3000.0)
    rec = Record({"v2": x}, 1e-4, 500)
    win, use = rec.test_window()
    assert win.n_samples == N_SAMPLES and win.event_index == EVENT_INDEX
    assert win["v2"][0] == 500 - EVENT_INDEX and win["v2"][-1] == 500 - EVENT_INDEX + N_SAMPLES - 1
    d = use.to_dict()
    assert d["samples_ignored_before"] == 452 and d["samples_ignored_after"] == 3000 - 452 - N_SAMPLES
    assert math.isclose(d["t_start"], -PRE_EVENT_TIME) and math.isclose(d["t_end"], POST_EVENT_TIME)


def test_channels_of_unequal_length_are_refused() -> None:
    with pytest.raises(RecordError, match="same number of samples"):
        Record({"a1": np.zeros(2048), "v2": np.zeros(2049)})


# -- units ---------------------------------------------------------------------------------------


def test_units_convert_once_and_round_trip() -> None:
    g = PROTOCOL_GRID
    rng = np.random.default_rng(0)
    raw = {c: rng.standard_normal(g.n_samples) for c in CHANNELS}
    units = {"a1": "g", "m_el": "N*m", "omega1": "rpm", "a2": "g", "v2": "mm/s"}
    rec = record_from_data(raw, 1e-4, 48, conditions={"base_torque": 250.0}, units=units)
    np.testing.assert_allclose(rec["a1"], raw["a1"] * STANDARD_GRAVITY, rtol=1e-15)
    np.testing.assert_allclose(rec["m_el"], raw["m_el"] / 250.0, rtol=1e-15)
    np.testing.assert_allclose(rec["omega1"], raw["omega1"] * 2 * math.pi / 60, rtol=1e-15)
    np.testing.assert_allclose(rec["v2"], raw["v2"] * 1e-3, rtol=1e-15)
    back = rec.to_dict()
    assert back["units"] == units
    for c in CHANNELS:
        np.testing.assert_allclose(back["channels"][c], raw[c], rtol=1e-12)
    again = Record.from_dict(back)
    for c in CHANNELS:
        np.testing.assert_array_equal(again[c], rec[c])


def test_omega1_in_pu_is_mechanical_base_speed() -> None:
    assert factor("omega1", "pu") == pytest.approx(OMEGA_B) == pytest.approx(2 * math.pi * 50 / 2)


@pytest.mark.parametrize(
    ("units", "conditions", "message"),
    [
        ({"a1": "ft/s^2"}, {}, r"unknown unit 'ft/s\^2' for channel 'a1'; accepted units: m/s\^2, g"),
        ({"omega1": "Hz"}, {}, "accepted units: rad/s, rpm, pu"),
        ({"m_el": "N*m"}, {}, "needs conditions.base_torque"),
        ({"v2": "m/s", "a2": "g"}, {}, "does not hold"),
    ],
)
def test_bad_units_are_refused_with_the_accepted_ones(units: dict, conditions: dict, message: str) -> None:
    chans = {c: np.zeros(2048) for c in ("a1", "m_el", "omega1", "v2")}
    with pytest.raises(RecordError, match=message):
        record_from_data(chans, 1e-4, 48, conditions=conditions, units=units)


# -- time column ---------------------------------------------------------------------------------


def test_time_column_defines_the_interval() -> None:
    g = SampleGrid.protocol(5e-5)
    t = np.round(0.37 + np.arange(g.n_samples) * 5e-5, 9)  # printed with 9 decimals, absolute times
    rec = record_from_data({"v2": np.zeros(g.n_samples)}, event_index=g.event_index, time=t)
    assert rec.sample_interval == pytest.approx(5e-5, rel=1e-9)


@pytest.mark.parametrize(
    ("t_change", "message"),
    [("jitter", "not uniform"), ("reverse", "must increase"), ("short", "has 4095 values")],
)
def test_bad_time_columns_are_refused(t_change: str, message: str) -> None:
    g = SampleGrid.protocol(5e-5)
    t = np.arange(g.n_samples) * 5e-5
    if t_change == "jitter":
        t[100] += 1e-5
    elif t_change == "reverse":
        t = t[::-1].copy()
    else:
        t = t[:-1]
    with pytest.raises(RecordError, match=message):
        record_from_data({"v2": np.zeros(g.n_samples)}, event_index=g.event_index, time=t)


def test_time_column_contradicting_sample_interval_is_refused() -> None:
    g = SampleGrid.protocol(5e-5)
    with pytest.raises(RecordError, match="contradicts the time column"):
        record_from_data({"v2": np.zeros(g.n_samples)}, 1e-4, g.event_index, time=np.arange(g.n_samples) * 5e-5)


def test_default_interval_reads_a_record_without_interval_or_time_column() -> None:
    """A record with neither ``sample_interval`` nor ``t`` is read at ``default_interval`` (a drive's protocol
    interval), MODEL.md's 0.1 ms without one; a time column or a given interval still wins."""
    g = SampleGrid.protocol(5e-5)  # 4096 samples, the event at 96: the test window at 50 us, 0.1 ms and 0.2 ms
    channels = {"v2": np.zeros(g.n_samples)}
    assert record_from_data(channels, event_index=g.event_index).sample_interval == 1e-4
    assert record_from_data(channels, event_index=g.event_index, default_interval=2e-4).sample_interval == 2e-4
    given = record_from_data(channels, 5e-5, g.event_index, default_interval=2e-4)
    assert given.sample_interval == 5e-5
    timed = record_from_data(
        channels, event_index=g.event_index, time=np.arange(g.n_samples) * 5e-5, default_interval=2e-4
    )
    assert timed.sample_interval == pytest.approx(5e-5, rel=1e-12)
    with pytest.raises(RecordError, match="contradicts the time column"):  # the two must still agree
        record_from_data(channels, 1e-4, g.event_index, time=np.arange(g.n_samples) * 5e-5, default_interval=5e-5)
    from_dict = Record.from_dict({"channels": {"v2": [0.0] * g.n_samples}, "event_index": 96}, default_interval=2e-4)
    assert from_dict.sample_interval == 2e-4


# -- event location --------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def rendered() -> dict[float, Record]:
    case = PlantParameters(K=0.0075, J1=0.85, c=1.0)
    return {ts: simulate(case, grid=SampleGrid.protocol(ts)) for ts in (2.5e-5, 1e-4, 5e-4)}


@pytest.mark.parametrize("ts", [2.5e-5, 1e-4, 5e-4])
@pytest.mark.parametrize("channel", ["m_el", "a1"])
@pytest.mark.parametrize("snr_db", [None, 30.0])
def test_event_is_located_from_m_el_or_a1(rendered: dict, ts: float, channel: str, snr_db: float | None) -> None:
    rec = rendered[ts]
    x = rec[channel]
    if snr_db is not None:
        x = add_white_noise(x, snr_db, np.random.default_rng(1))
    loc = locate_event({channel: x}, ts)
    assert loc.index == rec.event_index
    assert loc.channel == channel and loc.sigma == pytest.approx(ts / math.sqrt(12))


@pytest.mark.parametrize("offset", [-0.05, 0.08])
def test_event_is_located_from_m_el_with_an_offset(rendered: dict, offset: float) -> None:
    rec = rendered[2.5e-5]
    loc = locate_event({"m_el": rec["m_el"] + offset}, 2.5e-5)
    assert loc.index == rec.event_index and loc.channel == "m_el"


def test_record_without_event_index_carries_its_location(rendered: dict) -> None:
    rec = rendered[5e-4]
    data = rec.to_dict()
    del data["event_index"]
    again = Record.from_dict(data)
    assert again.event_index == rec.event_index
    assert again.event_location is not None and again.event_location.channel == "m_el"
    assert again.to_dict()["event_location"]["index"] == rec.event_index
    # a located record written and read back is still a located one
    assert Record.from_dict(again.to_dict()).event_location == again.event_location
    bad = again.to_dict()
    bad["event_location"]["index"] += 1
    with pytest.raises(RecordError, match="contradicts event_index"):
        Record.from_dict(bad)


def test_event_cannot_be_located_without_m_el_or_a1(rendered: dict) -> None:
    rec = rendered[1e-4]
    with pytest.raises(ProtocolError, match="give event_index"):
        record_from_data({"a2": rec["a2"], "v2": rec["v2"]}, 1e-4)


# -- resampling onto MODEL.md's grid --------------------------------------------------------------


def _tones(t: np.ndarray) -> np.ndarray:
    """A band-limited test signal (tones well below 500 Hz, the lowest Nyquist frequency accepted)."""
    return (
        np.sin(2 * np.pi * 37.0 * t + 0.3) + 0.5 * np.sin(2 * np.pi * 151.0 * t) + 0.2 * np.cos(2 * np.pi * 311.0 * t)
    )


@pytest.mark.parametrize("ts", [1e-5, 2.5e-5, 5e-5, 2e-4, 3e-4, 5e-4, 1e-3, 1.25e-4])
def test_resampling_reproduces_a_band_limited_signal(ts: float) -> None:
    g = SampleGrid.around_event(ts, 0.02, 0.25)
    x = _tones(g.time)
    y = resample_to_grid(x, g, PROTOCOL_GRID)
    ref = _tones(PROTOCOL_GRID.time)
    assert y.shape == ref.shape
    # interior and ends alike: resample_poly's anti-aliasing / interpolation filter, padded by the record itself
    assert np.max(np.abs(y - ref)) < 2e-3 * np.ptp(ref)


def test_resampling_removes_what_0_1_ms_cannot_hold() -> None:
    g = SampleGrid.around_event(1e-5, 0.02, 0.25)
    x = _tones(g.time) + np.sin(2 * np.pi * 7000.0 * g.time)  # above 5 kHz: must not alias into the band
    y = resample_to_grid(x, g, PROTOCOL_GRID)
    assert np.max(np.abs(y - _tones(PROTOCOL_GRID.time))) < 5e-3 * np.ptp(y)


def test_to_protocol_grid_of_a_model_record_is_its_window() -> None:
    rec = Record({"v2": np.arange(3000.0)}, 1e-4, 500)
    out = to_protocol_grid(rec)
    assert out.grid == PROTOCOL_GRID and out["v2"][0] == 452.0
