"""Records on any sample grid, and the measurement chain's trigger offset, gain and offset.

The kernel renders a record on any :class:`~engine.records.SampleGrid`; MODEL.md's grid
stays the default and is rendered exactly as before. Accuracy against the scipy
reference on other grids is in ``tests/test_simulation_accuracy.py``; here: the grid
bookkeeping, consistency between grids, and the exact formulas of the new sensor effects.
"""

from __future__ import annotations

import numpy as np
import pytest

from engine.constants import CHANNELS, EVENT_INDEX, N_SAMPLES, SAMPLE_INTERVAL
from engine.records import PROTOCOL_GRID, GridError, ProtocolError, SampleGrid
from engine.simulation import (
    CATALOGUE,
    Case,
    ParameterError,
    PlantParameters,
    SensorParameters,
    SolverSettings,
    simulate,
    simulate_batch,
)
from engine.simulation import _kernel as kern
from engine.simulation.simulator import parameter_vector, run_cases

NOMINAL = PlantParameters(K=0.005, J1=0.87, c=1.0)
PLANTS = [
    PlantParameters(K=0.01, J1=0.7612, c=1.4),
    PlantParameters(K=0.0025, J1=0.8482, c=0.8),
    PlantParameters(K=0.0075, J1=0.9135, c=1.25),
]
M_EL = CHANNELS.index("m_el")
OMEGA1 = CHANNELS.index("omega1")


@pytest.fixture(scope="module")
def protocol_plain():
    """The PLANTS on MODEL.md's grid, no effect."""
    return simulate_batch(PLANTS)


def common_instants(grid: SampleGrid, other: SampleGrid = PROTOCOL_GRID) -> tuple[np.ndarray, np.ndarray]:
    """Indices into ``grid`` and into ``other`` of the instants (relative to the event) both hold."""
    ratio = grid.sample_interval / other.sample_interval
    j = np.arange(grid.n_samples)
    pos = (j - grid.event_index) * ratio + other.event_index
    k = np.round(pos).astype(int)
    ok = np.isclose(pos, k, rtol=0, atol=1e-9) & (k >= 0) & (k < other.n_samples)
    return j[ok], k[ok]


def worst_relative(a: np.ndarray, b: np.ndarray, scale: np.ndarray) -> float:
    """Worst |a - b| over cases, channels and samples, as a fraction of ``scale`` (per case and channel)."""
    return float(np.max(np.max(np.abs(a - b), axis=-1) / scale))


# -- the grid ------------------------------------------------------------------------------
def test_default_grid_is_model_md_and_explicit_grids_render_the_same(protocol_plain):
    assert protocol_plain.grid == PROTOCOL_GRID
    assert protocol_plain.channels.shape == (len(PLANTS), len(CHANNELS), N_SAMPLES)
    explicit = simulate_batch(PLANTS, grid=SampleGrid(SAMPLE_INTERVAL, N_SAMPLES, EVENT_INDEX))
    np.testing.assert_array_equal(explicit.channels, protocol_plain.channels)
    np.testing.assert_array_equal(explicit.event_times, protocol_plain.event_times)
    rec = protocol_plain.record(0)
    assert (rec.sample_interval, rec.event_index, rec.n_samples) == (SAMPLE_INTERVAL, EVENT_INDEX, N_SAMPLES)


@pytest.mark.parametrize(
    "grid",
    [SampleGrid.protocol(5e-4), SampleGrid.protocol(1e-3), SampleGrid.around_event(2.5e-5, 0.03, 0.25)],
    ids=["0.5ms", "1ms", "25us-30ms-before"],
)
def test_records_come_on_the_requested_grid(grid):
    res = simulate_batch(PLANTS[:2], grid=grid)
    assert res.grid == grid
    assert res.channels.shape == (2, len(CHANNELS), grid.n_samples)
    assert res.channel("v2").shape == (2, grid.n_samples)
    rec = res.record(1)
    assert rec.grid == grid
    assert rec.event_time == res.event_times[1]
    np.testing.assert_array_equal(rec["a2"], res.channels[1, CHANNELS.index("a2")])
    # the event sits at the grid's event index: the motor torque vanishes there
    m_el = res.channels[:, M_EL]
    assert np.all(m_el[:, grid.event_index :] == 0.0)
    assert np.all(np.abs(m_el[:, grid.event_index - 1]) > 1e-3)
    # the same through simulate() and run_cases()
    single = simulate(PLANTS[1], grid=grid)
    np.testing.assert_array_equal(np.stack([single[c] for c in CHANNELS]), res.channels[1])
    ch, t_e, status = run_cases([Case(p) for p in PLANTS[:2]], grid=grid)
    assert status.tolist() == [kern.OK, kern.OK]
    np.testing.assert_array_equal(ch, res.channels)
    np.testing.assert_array_equal(t_e, res.event_times)


@pytest.mark.parametrize("ts", [5e-4, 1e-3, 3e-4])
def test_a_coarser_record_holds_the_fine_records_values_at_the_common_instants(protocol_plain, ts):
    """Ts a multiple of 0.1 ms: the same 33 us RK4 steps between the instants, so equal to far below the error.

    Only a step cut at a clutch-zone change splits the rest of its interval differently (up to
    the next instant of its own grid). Measured: 3.3e-11 of peak-to-peak at 0.5 and 1 ms,
    1.8e-6 at 0.3 ms (a2, a contact 160 ms after the event); the kernel's error against the
    scipy reference is up to 4.5e-4 on these plants.
    """
    grid = SampleGrid.protocol(ts)
    res = simulate_batch(PLANTS, grid=grid)
    j, k = common_instants(grid)
    assert len(j) >= grid.n_samples - 1  # every instant from 4.8 ms before the event on
    np.testing.assert_array_equal(res.event_times, protocol_plain.event_times)
    scale = np.ptp(protocol_plain.channels, axis=2)
    assert worst_relative(res.channels[:, :, j], protocol_plain.channels[:, :, k], scale) < 1e-5


@pytest.mark.parametrize(
    "grid",
    [SampleGrid.protocol(2.5e-5), SampleGrid.protocol(1e-5), SampleGrid.around_event(1e-4, 0.02, 0.3)],
    ids=["25us", "10us", "20ms-before"],
)
def test_a_finer_or_longer_record_agrees_with_model_md_record_to_the_integrator_error(protocol_plain, grid):
    """Other RK4 steps (the sample spacing) or another starting checkpoint: within the integrator's error.

    Measured: at most 3.4e-5 of peak-to-peak (a1, 10 us grid); the kernel's error against
    the scipy reference is up to 4.5e-4 on these plants.
    """
    res = simulate_batch(PLANTS, grid=grid)
    j, k = common_instants(grid)
    assert len(j) == N_SAMPLES  # every instant of MODEL.md's record
    np.testing.assert_array_equal(res.event_times, protocol_plain.event_times)
    scale = np.ptp(protocol_plain.channels, axis=2)
    assert worst_relative(res.channels[:, :, j], protocol_plain.channels[:, :, k], scale) < 1e-4


def test_history_reaches_back_as_far_as_the_grid_needs():
    """The checkpoint ring grows with the pre-event span; instants before switch-on read zeros."""
    # 25 ms before the event: past the former fixed 16 ms of history, but after switch-on
    deep = SampleGrid.around_event(1e-4, 0.025, 0.2)
    case = Case(PlantParameters(K=0.01, J1=0.7612, c=1.4))  # t_e ~ 46 ms
    ch, t_e, status = run_cases([case], grid=deep)
    assert status[0] == kern.OK and t_e[0] > 0.025
    assert np.all(np.abs(ch[0, M_EL, : deep.event_index]) > 0)  # the motor runs at every pre-event instant
    short, _, _ = run_cases([case])
    j, k = common_instants(deep)
    assert worst_relative(ch[:, :, j], short[:, :, k], np.ptp(short, axis=2)) < 1e-4
    # 200 ms before the event: the record starts before switch-on
    long = SampleGrid.around_event(5e-4, 0.2, 0.25)
    ch, t_e, status = run_cases([case], grid=long)
    assert status[0] == kern.OK
    t_abs = t_e[0] + long.time  # instants since switch-on
    assert np.all(ch[0][:, t_abs < 0] == 0.0)
    assert np.all(np.abs(ch[0, M_EL, (t_abs > 1e-3) & (long.time < 0)]) > 0)
    # the ring always covers the span it is sized for (checkpoints every CHECKPOINT_INTERVAL)
    for grid, shift in (
        (PROTOCOL_GRID, 0.0),
        (deep, 0.004),
        (long, -0.002),
        (SampleGrid.around_event(1e-5, 0.5, 0.2), 0),
    ):
        P = parameter_vector(Case(sensors=SensorParameters(trigger_offset=shift)), SolverSettings(), grid)
        span = min(grid.event_index * grid.sample_interval + max(shift, 0.0), P[kern.P_T_MAX])
        assert (kern.ring_size(P) - 2) * kern.CHECKPOINT_INTERVAL >= span
    assert kern.ring_size(parameter_vector(Case())) == kern.MIN_RING  # MODEL.md's grid: as before


# -- trigger offset ---------------------------------------------------------------------------
@pytest.mark.parametrize("grid", [PROTOCOL_GRID, SampleGrid.protocol(5e-4)], ids=["0.1ms", "0.5ms"])
def test_a_trigger_offset_equals_a_measurement_delay_of_the_same_size(grid):
    trig = simulate(NOMINAL, effects={"trigger_offset": 1e-3}, grid=grid)
    delay = simulate(NOMINAL, effects={"measurement_delay": 1e-3}, grid=grid)
    for c in CHANNELS:
        np.testing.assert_array_equal(trig[c], delay[c])
    # and a late trigger cancels a delay exactly (the shift is delay + trigger_offset = 0)
    both = simulate(Case(NOMINAL, SensorParameters(delay=7e-4, trigger_offset=-7e-4)), grid=grid)
    plain = simulate(NOMINAL, grid=grid)
    for c in CHANNELS:
        np.testing.assert_array_equal(both[c], plain[c])


@pytest.mark.parametrize("n", [3, -3])
def test_a_trigger_offset_moves_the_true_event_off_the_labelled_sample(n):
    """A positive offset: the true event lies after the labelled one (sample E + n); negative: before."""
    offset = n * SAMPLE_INTERVAL
    rec = simulate(NOMINAL, effects={"trigger_offset": offset})
    plain = simulate(NOMINAL)
    true_event = EVENT_INDEX + n
    assert np.all(rec["m_el"][true_event:] == 0.0)
    assert np.all(np.abs(rec["m_el"][:true_event]) > 1e-3)
    # the samples are the unshifted record's, moved by n (smooth channels: to the integrator's rounding)
    lo, hi = max(n, 0), N_SAMPLES + min(n, 0)
    for c in ("omega1", "v2", "a2"):
        np.testing.assert_allclose(rec[c][lo:hi], plain[c][lo - n : hi - n], rtol=0, atol=1e-6 * np.ptp(plain[c]))


# -- gain and offset --------------------------------------------------------------------------
def _plain_and(grid: SampleGrid, sensors: SensorParameters) -> tuple[np.ndarray, np.ndarray]:
    ch, _, status = run_cases([Case(NOMINAL), Case(NOMINAL, sensors)], grid=grid)
    assert status.tolist() == [kern.OK, kern.OK]
    return ch[0], ch[1]


def test_gain_scales_every_channel_exactly():
    plain, gained = _plain_and(PROTOCOL_GRID, SensorParameters(gain=1.15))
    np.testing.assert_array_equal(gained, 1.15 * plain)
    res = simulate_batch([NOMINAL], effects={"sensor_gain": 0.9})  # a multiplicative effect on gain 1
    assert res.cases[0].sensors.gain == 0.9
    np.testing.assert_array_equal(res.channels[0], 0.9 * plain)


@pytest.mark.parametrize(
    "grid", [PROTOCOL_GRID, SampleGrid.protocol(1e-3), SampleGrid.around_event(1e-4, 0.01, 0.4)], ids=str
)
def test_offset_is_value_times_the_channels_rms_over_the_test_window_after_the_gain(grid):
    plain, shifted = _plain_and(grid, SensorParameters(gain=1.1, offset_rms=-0.15))
    w = grid.window()
    assert w.stop - w.start == SampleGrid.protocol(grid.sample_interval).n_samples
    rms = np.sqrt(np.mean((1.1 * plain[:, w]) ** 2, axis=1))
    np.testing.assert_allclose(shifted, 1.1 * plain - 0.15 * rms[:, None], rtol=1e-14, atol=1e-14 * rms.max())


def test_the_offset_does_not_depend_on_the_record_length():
    short, long = PROTOCOL_GRID, SampleGrid.around_event(SAMPLE_INTERVAL, 0.02, 0.6)
    sensors = SensorParameters(offset_rms=0.2)
    plain_s, off_s = _plain_and(short, sensors)
    plain_l, off_l = _plain_and(long, sensors)
    added_s = (off_s - plain_s)[:, 0]
    added_l = (off_l - plain_l)[:, 0]
    np.testing.assert_allclose(added_l, added_s, rtol=1e-9)
    # the RMS of the whole long record differs markedly (omega1 settles, v2 decays after 200 ms)
    rms_whole = np.sqrt(np.mean(plain_l**2, axis=1))
    assert np.max(np.abs(0.2 * rms_whole - added_s) / np.abs(added_s)) > 0.05


def test_quantisation_comes_after_gain_and_offset():
    q = 0.25
    plain, read = _plain_and(PROTOCOL_GRID, SensorParameters(gain=0.9, offset_rms=0.1, speed_quantum=q))
    w = PROTOCOL_GRID.window()
    analog = 0.9 * plain[OMEGA1]
    analog = analog + 0.1 * np.sqrt(np.mean(analog[w] ** 2))
    np.testing.assert_array_equal(read[OMEGA1], q * np.round(analog / q))
    np.testing.assert_allclose(read[M_EL], 0.9 * plain[M_EL] + 0.1 * np.sqrt(np.mean((0.9 * plain[M_EL]) ** 2)))


def test_an_offset_needs_a_grid_that_covers_the_test_window():
    short = SampleGrid(SAMPLE_INTERVAL, 1000, EVENT_INDEX)  # 95 ms after the event
    ch, _, status = run_cases([Case(NOMINAL)], grid=short)  # without an offset any grid renders
    assert status[0] == kern.OK and ch.shape == (1, len(CHANNELS), 1000)
    with pytest.raises(GridError, match="200 ms after"):
        simulate_batch([NOMINAL], effects={"sensor_offset": 0.1}, grid=short)
    with pytest.raises(ProtocolError, match="missing"):
        simulate_batch([NOMINAL], grid=short).record(0)


# -- the catalogue rows and validation ---------------------------------------------------------
def test_new_catalogue_rows():
    rows = {name: CATALOGUE[name] for name in ("trigger_offset", "sensor_gain", "sensor_offset")}
    assert [(e.target, e.field, e.mode, e.bounds, e.neutral, e.unit) for e in rows.values()] == [
        ("sensors", "trigger_offset", "set", (-2e-3, 2e-3), 0.0, "s"),
        ("sensors", "gain", "multiply", (0.8, 1.2), 1.0, "x"),
        ("sensors", "offset_rms", "set", (-0.2, 0.2), 0.0, "x RMS"),
    ]
    assert SensorParameters() == SensorParameters(trigger_offset=0.0, gain=1.0, offset_rms=0.0)


@pytest.mark.parametrize(
    "sensors,match",
    [
        (SensorParameters(trigger_offset=6e-3), "trigger_offset"),
        (SensorParameters(trigger_offset=-6e-3), "trigger_offset"),
        (SensorParameters(gain=0.0), "gain"),
        (SensorParameters(offset_rms=1.5), "offset_rms"),
        (SensorParameters(gain=float("nan")), "finite"),
    ],
)
def test_absurd_sensor_values_raise(sensors, match):
    with pytest.raises(ParameterError, match=match):
        simulate(Case(NOMINAL, sensors))


def test_the_largest_negative_shift_renders():
    """A trigger 5 ms late on a grid starting at the event: every instant after t_e."""
    grid = SampleGrid(1e-3, 205, 0)
    ch, _, status = run_cases([Case(NOMINAL, SensorParameters(trigger_offset=-5e-3))], grid=grid)
    plain, _, _ = run_cases([Case(NOMINAL)], grid=SampleGrid(1e-3, 210, 0))
    assert status[0] == kern.OK
    np.testing.assert_allclose(ch[0], plain[0][:, 5:], rtol=0, atol=1e-9 * np.ptp(plain[0], axis=1).max())


# -- rendering the first samples only ------------------------------------------------------------
@pytest.mark.parametrize(
    "sensors",
    [
        SensorParameters(),
        SensorParameters(delay=3e-4, lowpass_hz=800.0),
        SensorParameters(trigger_offset=-1.5e-3, gain=1.1, speed_quantum=0.05),
        SensorParameters(offset_rms=0.12),  # its RMS needs the whole test window: rendered whole, then cut
    ],
    ids=["plain", "delay-lowpass", "trigger-gain-quantum", "offset"],
)
@pytest.mark.parametrize("grid", [PROTOCOL_GRID, SampleGrid.around_event(2e-4, 0.01, 0.3)], ids=str)
def test_the_first_samples_alone_are_those_of_the_whole_record(sensors, grid):
    cases = [Case(PLANTS[0], sensors), Case(PLANTS[1])]
    whole, t_e, status = run_cases(cases, grid=grid)
    assert status.tolist() == [kern.OK, kern.OK]
    for first in (1, grid.event_index, grid.event_index + 7, grid.n_samples // 3, grid.n_samples):
        part, t_e2, status2 = run_cases(cases, grid=grid, first=first)
        assert part.shape == (2, len(CHANNELS), first)
        np.testing.assert_array_equal(part, whole[:, :, :first])  # bit for bit
        np.testing.assert_array_equal(t_e2, t_e)
        assert status2.tolist() == status.tolist()


@pytest.mark.parametrize("first", [0, -3, N_SAMPLES + 1, 10.5, True])
def test_a_first_sample_count_outside_the_grid_is_refused(first):
    with pytest.raises(ValueError, match="first must be a sample count from 1 to 2048"):
        run_cases([Case(NOMINAL)], first=first)
