"""The plausibility gate (issue 50, item 3): the record boundary's magnitude limit, a noise estimate that
never overflows, and the warnings of engine.diagnosis.plausibility on records the plant cannot produce."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from engine.constants import CHANNELS
from engine.diagnosis import plausibility
from engine.diagnosis.calibration import CalibrationResult, calibrate
from engine.diagnosis.noise import estimate_noise, noise_weights
from engine.diagnosis.plausibility import (
    PlausibilityWarning,
    check_calibration,
    check_record,
    merge_warnings,
    peak_envelope,
)
from engine.plants.brfd import record as brfd_record
from engine.plants.emps import record as emps_record
from engine.records import Record, RecordError, SampleGrid, record_from_data
from engine.records.limits import MAX_ABS_SAMPLE, MAX_SAMPLES
from engine.simulation import CATALOGUE, PlantParameters, simulate, simulate_batch
from engine.simulation.noise import noise_std

TRUTH = PlantParameters(K=0.0063, J1=0.845, c=1.22)
RPM = 60.0 / (2.0 * math.pi)
G = 9.80665


def noisy(record: Record, seed: int = 0, snr_db: float = 40.0) -> Record:
    """``record`` with white noise of ``snr_db`` on every channel, c1 known (as the calibration tests)."""
    rng = np.random.default_rng(seed)
    ch = {k: x + rng.standard_normal(x.size) * float(noise_std(x, snr_db)[0]) for k, x in record.channels.items()}
    return Record(ch, record.sample_interval, record.event_index, conditions={"c1": 0.2})


def codes(warnings: list[PlausibilityWarning]) -> list[tuple[str, str | None]]:
    return [(w.code, w.channel) for w in warnings]


def unchecked(record: Record, scale: float) -> Record:
    """``record`` with every channel multiplied by ``scale``, bypassing the boundary (what it used to let in)."""
    out = object.__new__(Record)
    for f in dataclasses.fields(Record):
        object.__setattr__(out, f.name, getattr(record, f.name))
    object.__setattr__(out, "channels", {c: x * scale for c, x in record.channels.items()})
    return out


@pytest.fixture(scope="module")
def clean() -> Record:
    return noisy(simulate(TRUTH))


@pytest.fixture(scope="module")
def long_clean() -> Record:
    """``clean``'s plant sampled at 0.1 ms for 48 ms before the event and 2 s after it: 10x the test window, so that
    it can be declared at 10 us (0.1x its interval) and still cover the window."""
    return noisy(simulate(TRUTH, grid=SampleGrid.around_event(1e-4, 48e-3, 2.0)), seed=3)


@pytest.fixture(scope="module")
def clean_fit(clean: Record) -> CalibrationResult:
    return calibrate(clean)


@pytest.fixture(scope="module")
def rpm_fit(clean: Record) -> tuple[Record, CalibrationResult]:
    """omega1 alone, in rpm but read as rad/s (as ``identify --continuous`` fits one channel)."""
    rec = Record({"omega1": clean["omega1"] * RPM}, conditions={"c1": 0.2})
    return rec, calibrate(rec)


@pytest.fixture(scope="module")
def g_fit(clean: Record) -> tuple[Record, CalibrationResult]:
    """Every channel, a1 in g but read as m/s^2."""
    rec = clean.replace(channels={**clean.channels, "a1": clean["a1"] / G})
    return rec, calibrate(rec)


@pytest.fixture(scope="module")
def slow_fit(clean: Record) -> tuple[Record, CalibrationResult]:
    """Every channel, the 0.1 ms samples declared at 1 ms (10x too long)."""
    rec = clean.replace(sample_interval=1e-3)
    return rec, calibrate(rec)


# -- the record boundary ---------------------------------------------------------------------------
def test_the_boundary_refuses_values_no_computation_survives(clean: Record) -> None:
    omega1 = clean["omega1"].copy()
    omega1[123] = 1e200
    message = r"channel 'omega1' holds 1e\+200 rad/s at sample 123: .*check the record's units"
    with pytest.raises(RecordError, match=message):
        Record({**clean.channels, "omega1": omega1})
    with pytest.raises(RecordError, match=r"channel 'a1' holds .* at sample 0"):  # every value x 1e200
        Record({c: x * 1e200 for c, x in clean.channels.items()})
    # the limit is in the model's unit, after the declared unit's conversion, and the message says so
    rpm = (clean["omega1"] * 1e13).tolist()  # 2.6e12 rad/s at sample 0
    with pytest.raises(RecordError, match=r"channel 'omega1' \(given in rpm\) holds .* rad/s at sample 0"):
        record_from_data({"omega1": rpm}, units={"omega1": "rpm"}, event_index=48)
    # a record in a wrong unit, or in raw counts, is not refused: it gets a warning instead
    assert MAX_ABS_SAMPLE == 1e12
    Record({**clean.channels, "v2": clean["v2"] * 1e9})
    Record({**clean.channels, "v2": np.full(clean.n_samples, MAX_ABS_SAMPLE)})


def test_the_other_plants_records_refuse_them_too() -> None:
    n = 600
    t = np.arange(n) * emps_record.SAMPLE_INTERVAL
    arrays = {"t": t, "qm": np.zeros(n), "qg": np.zeros(n), "vir": np.zeros(n)}
    arrays["qm"][7] = -3e15
    with pytest.raises(RecordError, match=r"run1: qm holds -3e\+15 m at sample 7"):
        emps_record.record_from_arrays(arrays, {"kp": 1.0, "kv": 1.0, "gtau": 1.0}, "run1")
    force = np.zeros(1024)
    force[9] = 1e200
    with pytest.raises(RecordError, match=r"test: friction force \(given in kip\) holds 4.45e\+203 N at sample 9"):
        brfd_record.record_from_arrays(np.arange(1024) / 1024, np.zeros(1024), force, "test", "in", "kip")
    force[9] = 1e10  # 4.4e13 N: beyond the limit in SI units
    with pytest.raises(RecordError, match=r"test: friction force \(given in kip\) holds 4.45e\+13 N at sample 9"):
        brfd_record.record_from_arrays(np.arange(1024) / 1024, np.zeros(1024), force, "test", "in", "kip")


@pytest.mark.parametrize("rounding", [0.0, 1e-16, 1e-13])
def test_a_stuck_channel_is_refused_whatever_the_rounding_of_its_reading(rounding: float) -> None:
    """An EMPS encoder stuck at 0.25 m: its position is the zero-phase filter of a constant, which
    varies by about 1e-15 of it by the platform's arithmetic (or by a rounding of the values sent),
    and is refused all the same; a position that moves by a micrometre is not."""
    from engine.diagnosis.plant_plausibility import ConstantChannelError, check_channels
    from engine.plants import get_plant

    n = 1000
    t = np.arange(n) * emps_record.SAMPLE_INTERVAL
    qm = 0.25 + rounding * np.random.default_rng(0).standard_normal(n)
    gains = {"kp": 1.0, "kv": 1.0, "gtau": 1.0}
    vir = np.sin(np.arange(n) / 50.0)
    stuck = emps_record.record_from_arrays({"t": t, "qm": qm, "qg": qm, "vir": vir}, gains, "stuck")
    with pytest.raises(ConstantChannelError, match=r"channel position is 0\.25 m at every one of its"):
        check_channels(get_plant("emps"), stuck)
    moving = 0.25 + 1e-6 * np.sin(np.arange(n) / 80.0)
    check_channels(
        get_plant("emps"), emps_record.record_from_arrays({"t": t, "qm": moving, "qg": moving, "vir": vir}, gains, "m")
    )


def test_a_record_longer_than_the_cap_is_refused_on_every_plant(clean: Record) -> None:
    """One cap on samples per record at every plant's boundary (issue 51, item 2): refused, saying what to send."""
    n = MAX_SAMPLES + 1
    with pytest.raises(RecordError, match=rf"channel 'a1' has {n} samples, more than the {MAX_SAMPLES}"):
        Record({"a1": np.zeros(n)}, clean.sample_interval, clean.event_index)
    t = np.arange(n) * emps_record.SAMPLE_INTERVAL
    arrays = {"t": t, "qm": np.zeros(n), "qg": np.zeros(n), "vir": np.zeros(n)}
    with pytest.raises(RecordError, match=r"run1: t has \d+ samples, more than"):
        emps_record.record_from_arrays(arrays, {"kp": 1.0, "kv": 1.0, "gtau": 1.0}, "run1")
    with pytest.raises(RecordError, match=r"test: time has \d+ samples, more than"):
        brfd_record.record_from_arrays(np.arange(n) / 1024, np.zeros(n), np.zeros(n), "test", "m", "N")
    Record({"a1": np.zeros(MAX_SAMPLES)}, clean.sample_interval, clean.event_index)  # the cap itself is accepted


def test_the_noise_estimate_never_overflows(clean: Record) -> None:
    """Values x 1e200 used to give an infinite noise (zero residuals, a confident no_gap); now exactly scaled."""
    small = estimate_noise(clean)
    big = estimate_noise(unchecked(clean, 1e200))
    for c in CHANNELS:
        assert math.isfinite(big[c]) and big[c] == pytest.approx(1e200 * small[c], rel=1e-9), c
    weights = noise_weights(unchecked(clean, 1e200), big)
    assert all(math.isfinite(weights[c]) and weights[c] > 0 for c in CHANNELS)
    with pytest.raises(RecordError, match="the noise of channel 'a1' cannot be estimated"):
        estimate_noise(unchecked(clean, math.inf))


# -- checks without a fit --------------------------------------------------------------------------
def test_the_plants_range_of_peaks() -> None:
    env = peak_envelope()
    assert set(env) == set(CHANNELS)
    lo, hi = env["omega1"]
    assert 1.0 < lo < 3.0 < 8.0 < hi < 10.0  # rad/s: the slow motor of the backlash test
    assert 20.0 < env["a1"][0] < env["a1"][1] < 200.0


def test_check_record_names_the_unit_of_a_channel_out_of_range(clean: Record) -> None:
    assert check_record(clean) == []
    rpm = check_record(clean.replace(channels={**clean.channels, "omega1": clean["omega1"] * RPM}))
    assert codes(rpm) == [("channel_scale", "omega1")]
    assert "is it in rpm?" in rpm[0].message and '"units": {"omega1": "rpm"}' in rpm[0].message
    g = check_record(clean.replace(channels={**clean.channels, "a1": clean["a1"] / G}))
    assert codes(g) == [("channel_scale", "a1")] and "is it in g?" in g[0].message
    percent = check_record(clean.replace(channels={"m_el": clean["m_el"] * 100.0}))
    assert "is it in %?" in percent[0].message and "multiply its values by 0.01" in percent[0].message
    # declared in rpm but given in rad/s: the suspect is the model's own unit
    declared = record_from_data({"omega1": clean["omega1"].tolist()}, units={"omega1": "rpm"}, event_index=48)
    (w,) = check_record(declared)
    assert w.code == "channel_scale" and "is it in rad/s?" in w.message
    # a stuck sensor
    (w,) = check_record(clean.replace(channels={**clean.channels, "v2": np.full(clean.n_samples, 0.25)}))
    assert (w.code, w.channel) == ("constant_channel", "v2") and "0.25 m/s" in w.message


def test_the_load_rise_time_is_a_time_of_the_signal_not_of_its_grid_or_unit(clean: Record) -> None:
    v2 = clean["v2"]
    t = plausibility.rise_time(v2, 1e-4)
    lo, hi = plausibility.rise_envelope()["v2"]
    assert 1e-3 < lo <= t <= hi < 6e-3  # ms: the load's motion, far slower than a sample
    assert plausibility.rise_time(3.6 * v2 + 0.4, 1e-4) == pytest.approx(t, rel=1e-6)  # unit, gain and offset
    assert plausibility.rise_time(v2, 1e-3) == pytest.approx(10 * t, rel=1e-6)  # the same samples, 10x slower
    coarse = simulate(TRUTH, grid=SampleGrid.protocol(1e-3))["v2"]  # the plant sampled at 1 ms
    assert plausibility.rise_time(coarse, 1e-3) == pytest.approx(t, rel=0.1)
    assert math.isnan(plausibility.rise_time(np.full(100, 0.3), 1e-4))


def test_check_record_suspects_a_sample_interval_10x_wrong_without_a_fit(long_clean: Record) -> None:
    assert check_record(long_clean) == []
    slow = check_record(long_clean.replace(sample_interval=1e-3))  # the CSV: 1 ms declared for 0.1 ms
    assert codes(slow) == [("sample_interval", None)]
    assert "looks 10x slower than the plant's" in slow[0].message
    assert "0.0001 s instead of the declared 0.001 s" in slow[0].message
    assert "is the sample interval (or the time column) right?" in slow[0].message
    fast = check_record(long_clean.replace(sample_interval=1e-5))  # 0.1x: 10 us declared for 0.1 ms
    assert codes(fast) == [("sample_interval", None)]
    assert "10x faster" in fast[0].message and "0.0001 s instead of the declared 1e-05 s" in fast[0].message
    # each witness of the load's motion alone (as identify checks the channel it identifies)
    for channel in ("v2", "a2"):
        alone = long_clean.replace(channels={channel: long_clean[channel]})
        assert check_record(alone) == []
        for declared in (1e-3, 1e-5):
            assert codes(check_record(alone.replace(sample_interval=declared))) == [("sample_interval", None)]
    # the motor side is not read (its time scales are the contact's and the switch-off's): the fit's check is its witness
    omega1 = long_clean.replace(channels={"omega1": long_clean["omega1"]}, sample_interval=1e-3)
    assert check_record(omega1) == []


def test_catalogued_effects_at_their_bounds_are_not_a_sample_interval() -> None:
    """The load's effects that move its time scale most, each at the bound that moves it most (module docstring)."""
    effects = [{"resilient_stiffness": 0.5}, {"absorber_discontinuity": 3.0}, {"load_inertia": 2.0}]
    for name in ("contact_stiffness", "resilient_stiffness", "load_inertia"):
        effects.append({name: CATALOGUE[name].bounds[1]})
    corner = PlantParameters(K=0.015, J1=1.2, c=0.5, c1=0.6)
    sims = simulate_batch([corner] * len(effects), effects)
    for i, effect in enumerate(effects):
        assert "sample_interval" not in {w.code for w in check_record(noisy(sims.record(i), seed=i))}, effect


def test_warnings_are_json_ready_and_merged_without_repeats() -> None:
    a = PlausibilityWarning("misfit", "x", "a1")
    assert a.to_dict() == {"code": "misfit", "message": "x", "channel": "a1"}
    b = PlausibilityWarning("misfit", "y", "a1")
    c = PlausibilityWarning("sample_interval", "z")
    assert merge_warnings([a], [b, c], [c]) == [a, c]


# -- checks on a calibration -----------------------------------------------------------------------
def test_a_clean_record_gives_no_warning(clean: Record, clean_fit: CalibrationResult) -> None:
    assert check_calibration(clean, clean_fit) == []
    evidence, _ = plausibility.time_scale_evidence(clean, clean_fit)
    assert evidence < 0.1  # every other reading of the interval fits far worse


def test_omega1_in_rpm(rpm_fit: tuple[Record, CalibrationResult]) -> None:
    rec, cal = rpm_fit
    warnings = check_calibration(rec, cal)
    assert codes(warnings) == [("channel_scale", "omega1"), ("misfit", "omega1")]
    assert "is it in rpm?" in warnings[0].message and "never exceeds" in warnings[0].message
    assert "does not reproduce the record" in warnings[1].message


def test_a1_in_g(g_fit: tuple[Record, CalibrationResult]) -> None:
    rec, cal = g_fit
    warnings = check_calibration(rec, cal)
    assert codes(warnings)[0] == ("channel_scale", "a1") and "is it in g?" in warnings[0].message
    assert [w.channel for w in warnings if w.code == "channel_scale"] == ["a1"]
    assert "sample_interval" not in {w.code for w in warnings}
    assert ("misfit", "a1") in codes(warnings)


def test_the_fits_scale_names_the_unit_when_the_range_does_not(clean: Record, monkeypatch: pytest.MonkeyPatch) -> None:
    """The least-squares scale between record and calibrated simulation is a second, independent witness.

    Every channel, omega1 in rpm: the other channels pin the fit, and the record's omega1 is 9.2 x the
    calibrated one (rpm: 9.55).
    """
    rec = clean.replace(channels={**clean.channels, "omega1": clean["omega1"] * RPM})
    cal = calibrate(rec)
    monkeypatch.setattr(plausibility, "RANGE_MARGIN", 1e9)  # the range check sees nothing
    scale = [w for w in check_calibration(rec, cal) if w.code == "channel_scale"]
    assert codes(scale) == [("channel_scale", "omega1")]
    assert "only scaled" in scale[0].message and "is it in rpm rather than rad/s?" in scale[0].message
    monkeypatch.setattr(plausibility, "UNIT_MATCH", 1.01)  # no unit within 1 %: no claim
    assert "channel_scale" not in {w.code for w in check_calibration(rec, cal)}


def test_a_sample_interval_10x_too_long(slow_fit: tuple[Record, CalibrationResult]) -> None:
    rec, cal = slow_fit
    # its values are the plant's: only its dynamics give it away, the load's rise time already without a fit
    assert codes(check_record(rec)) == [("sample_interval", None)]
    warnings = check_calibration(rec, cal)
    assert codes(warnings)[0] == ("sample_interval", None)
    assert "10x slower" in warnings[0].message and "0.0001 s instead of the declared 0.001 s" in warnings[0].message
    assert all(w.code in ("sample_interval", "misfit") for w in warnings)


def test_an_unmodelled_effect_is_a_misfit_not_a_unit_or_interval(clean: Record) -> None:
    rec = noisy(simulate_batch([TRUTH], {"load_inertia": 1.3}).record(0), seed=1)
    assert check_record(rec) == []
    warnings = check_calibration(rec, calibrate(rec))
    assert warnings and {w.code for w in warnings} == {"misfit"}


def test_check_calibration_refuses_a_calibration_of_another_record(
    clean_fit: CalibrationResult, slow_fit: tuple[Record, CalibrationResult]
) -> None:
    with pytest.raises(ValueError, match="pass the record that was calibrated"):
        check_calibration(slow_fit[0], clean_fit)
