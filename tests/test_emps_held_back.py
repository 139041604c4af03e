"""The EMPS plant's held-back family, entries and locus signals (issue 52).

The held-back effects are outside the catalogue: the plant simulates them (neutral = the model
unchanged, bit for bit), and each is visible above the plant's own noise at mid-range. The entries
add a force in the loop (``force``) and an error of the recorded position (``position``); the
locus signals are what a missing term at each locus would follow.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from engine.plants.base import LocusSignal
from engine.plants.emps import CATALOGUE, HELD_BACK, LOCI, PUBLISHED, SEALED, EmpsParameters, EmpsPlant, EmpsRecord
from engine.plants.emps.catalogue import EFFECT_FIELDS, HELD_BACK_FIELDS, SEALED_FIELDS
from engine.plants.emps.channels import process
from engine.plants.emps.model import (
    CONTAMINATION_POSITION,
    POSITION_FRICTION_PERIOD,
    SLIP_SHARE,
    vibration_force,
)

CHANNEL_NAMES = ("position", "velocity", "acceleration", "force")


@pytest.fixture(scope="module")
def plant() -> EmpsPlant:
    return EmpsPlant()


@pytest.fixture(scope="module")
def record(plant: EmpsPlant) -> EmpsRecord:
    return plant.example(seconds=12)


@pytest.fixture(scope="module")
def nominal(plant: EmpsPlant, record: EmpsRecord) -> dict[str, np.ndarray]:
    return plant.simulate(record, {})


def _mid(name: str) -> float:
    """Mid-range value of a held-back scalar (of its magnitude when its interval is symmetric about neutral)."""
    lo, hi = HELD_BACK[name].bounds
    return 0.5 * hi if lo == -hi else 0.5 * (lo + hi)


# -- the held-back family ----------------------------------------------------------------


def test_the_held_back_family_is_one_effect_per_locus_outside_the_catalogue(plant: EmpsPlant) -> None:
    assert set(plant.held_back) == {
        "amplifier_dead_band",
        "quadratic_drag",
        "screw_force_ripple",
        "cable_spring",
        "position_log_skew",
    }
    assert not set(plant.held_back) & set(plant.catalogue)
    assert not set(plant.held_back) & {p.name for p in plant.calibrated}
    assert sorted(e.locus for e in plant.held_back.values()) == sorted(LOCI)
    for name, e in plant.held_back.items():
        assert e.name == name and e.unit and e.description
        assert e.neutral == 0.0 and e.bounds[0] < e.bounds[1]
    assert dict(plant.held_back) == HELD_BACK and not set(HELD_BACK) & set(CATALOGUE)


def test_neutral_held_back_values_leave_the_model_unchanged_bit_for_bit(
    plant: EmpsPlant, record: EmpsRecord, nominal: dict[str, np.ndarray]
) -> None:
    neutral = {name: e.neutral for name, e in plant.held_back.items()}
    for values in ({}, {"stribeck": -8.0, "actuator_delay": 0.0015}):
        plain = plant.states(record, values)
        held = plant.states(record, {**values, **neutral})
        for c in CHANNEL_NAMES:
            np.testing.assert_array_equal(held[c], plain[c])
    sim = plant.simulate(record, neutral)
    for c in CHANNEL_NAMES:
        np.testing.assert_array_equal(sim[c], nominal[c])
    with pytest.raises(KeyError):
        plant.simulate(record, {"cable_springs": 100.0})


@pytest.mark.parametrize("name", sorted(HELD_BACK))
def test_each_held_back_effect_at_mid_range_changes_the_channels_beyond_the_noise(
    name: str, plant: EmpsPlant, record: EmpsRecord, nominal: dict[str, np.ndarray]
) -> None:
    noise = plant.noise(record)
    sl = plant.scored(record)
    sim = plant.simulate(record, {name: _mid(name)})
    ratio = {c: float(np.sqrt(np.mean(np.square(sim[c][sl] - nominal[c][sl])))) / noise[c].sigma for c in CHANNEL_NAMES}
    # above the noise on two channels at least (the position's noise, the encoder's quantum, is tiny)
    assert sum(r > 1.0 for r in ratio.values()) >= 2, ratio
    assert max(ratio.values()) > 10.0, ratio


def test_the_log_skew_delays_the_recorded_position_only(plant: EmpsPlant, record: EmpsRecord) -> None:
    delta = 0.0015  # 1.5 samples
    plain = plant.states(record, {})
    skewed = plant.states(record, {"position_log_skew": delta})
    for c in ("velocity", "acceleration", "force"):  # the loop is unchanged
        np.testing.assert_array_equal(skewed[c], plain[c])
    q = plain["position"]
    np.testing.assert_allclose(skewed["position"][2:], 0.5 * (q[:-2] + q[1:-1]), rtol=0, atol=1e-15)
    assert skewed["position"][0] == q[0]


def test_the_dead_band_keeps_the_force_channel_on_the_command(plant: EmpsPlant, record: EmpsRecord) -> None:
    """The force channel reads g_tau v, the command, while the drive gives g_tau dz(v, v0): less force."""
    x = plant.states(record, {"amplifier_dead_band": 0.3})
    ref = plant.states(record, {})
    sl = plant.scored(record)
    # the loop commands more to overcome the dead band: the commanded force grows in magnitude
    assert np.mean(np.abs(x["force"][sl])) > np.mean(np.abs(ref["force"][sl]))


# -- entries -------------------------------------------------------------------------------


def test_the_entries_are_a_force_and_a_position(plant: EmpsPlant) -> None:
    assert dict(plant.entries) == {"force": "N", "position": "m"}


def test_an_unknown_entry_or_a_bad_schedule_is_refused(plant: EmpsPlant, record: EmpsRecord) -> None:
    n = record.n
    with pytest.raises(KeyError, match="torque"):
        plant.simulate(record, {}, inputs={"torque": np.zeros(n)})
    for name in plant.entries:
        with pytest.raises(ValueError, match="per sample"):
            plant.simulate(record, {}, inputs={name: np.zeros(n - 1)})
        with pytest.raises(ValueError, match="per sample"):
            plant.simulate(record, {}, inputs={name: np.zeros((n, 1))})
        bad = np.zeros(n)
        bad[n // 2] = math.nan
        with pytest.raises(ValueError, match="non-finite"):
            plant.simulate(record, {}, inputs={name: bad})


def test_zero_inputs_leave_the_channels_unchanged(
    plant: EmpsPlant, record: EmpsRecord, nominal: dict[str, np.ndarray]
) -> None:
    sim = plant.simulate(record, {}, inputs={"force": np.zeros(record.n), "position": np.zeros(record.n)})
    for c in CHANNEL_NAMES:
        np.testing.assert_array_equal(sim[c], nominal[c])


@pytest.mark.parametrize("c", [2.0, -5.0])
def test_a_constant_force_input_is_the_offset_lowered_by_it(plant: EmpsPlant, record: EmpsRecord, c: float) -> None:
    """The offset is counted opposing the drive (``_motor_force`` is subtracted from ``g_tau v``), the
    force entry pushes forward like the drive: a constant input c is the offset lowered by c."""
    with_input = plant.simulate(record, {}, inputs={"force": np.full(record.n, c)})
    lowered = plant.simulate(record, {"offset": PUBLISHED["offset"] - c})
    for ch in CHANNEL_NAMES:
        scale = float(np.max(np.abs(lowered[ch])))
        np.testing.assert_allclose(with_input[ch], lowered[ch], rtol=1e-9, atol=1e-9 * scale)
    # and it is not nothing: the same input moves the nominal model
    assert not np.allclose(with_input["force"], plant.simulate(record, {})["force"])


def test_a_position_input_reaches_the_channels_through_the_filter(
    plant: EmpsPlant, record: EmpsRecord, nominal: dict[str, np.ndarray]
) -> None:
    error = np.where(record.t >= record.t[record.n // 2], 1e-4, 0.0)  # a 0.1 mm step of the sensor
    sim = plant.simulate(record, {}, inputs={"position": error})
    through = process(error, np.zeros(record.n), record.ts)
    for c in CHANNEL_NAMES:  # the loop is untouched: the difference is the chain's response to the error
        scale = float(np.max(np.abs(nominal[c]))) + float(np.max(np.abs(through[c])))
        np.testing.assert_allclose(sim[c] - nominal[c], through[c], rtol=0, atol=1e-9 * scale)
    np.testing.assert_array_equal(sim["force"], nominal["force"])
    # filtered: a ramp over several samples, not a step, settling at the step's size
    shift = sim["position"] - nominal["position"]
    assert 0.0 < shift[record.n // 2 - 1] < 1e-4 and 0.0 < shift[record.n // 2] < 1e-4
    assert shift[record.n // 2 + 50] == pytest.approx(1e-4, rel=1e-6)


# -- locus signals ---------------------------------------------------------------------------


def test_the_locus_signals_state_what_each_locus_sees(plant: EmpsPlant, record: EmpsRecord) -> None:
    signals = plant.locus_signals(record, {})
    assert all(isinstance(s, LocusSignal) for s in signals)
    assert [(s.locus, s.entry, s.signal, s.unit) for s in signals] == [
        ("drive", "force", "command force", "N"),
        ("guide", "force", "velocity", "m/s"),
        ("transmission", "force", "screw angle", "m"),
        ("load", "force", "position", "m"),
        ("load", "force", "time", "s"),
        ("sensors", "position", "position", "m"),
        ("sensors", "position", "velocity", "m/s"),
    ]
    for s in signals:
        assert s.locus in plant.loci and s.entry in plant.entries
        assert s.values.shape == (record.n,) and np.all(np.isfinite(s.values))
        assert s.factor is None
    by = {(s.locus, s.signal): s for s in signals}
    x = plant.states(record, {})
    np.testing.assert_array_equal(by["drive", "command force"].values, x["force"])
    np.testing.assert_array_equal(by["guide", "velocity"].values, x["velocity"])
    np.testing.assert_array_equal(by["load", "position"].values, x["position"])
    np.testing.assert_array_equal(by["sensors", "position"].values, x["position"])
    np.testing.assert_array_equal(by["load", "time"].values, plant.time(record))
    angle = by["transmission", "screw angle"]
    assert angle.period == POSITION_FRICTION_PERIOD
    assert np.all((angle.values >= 0.0) & (angle.values < POSITION_FRICTION_PERIOD))
    np.testing.assert_allclose(angle.values, np.mod(x["position"], POSITION_FRICTION_PERIOD))
    assert all(s.period is None for s in signals if s is not angle)


# -- the sealed family (scored once) ---------------------------------------------------------
# Defined before any diagnosis ran on them; development never reads their scores. These tests
# only simulate them (no diagnosis, no locus estimate).


def _sealed_mid(name: str) -> float:
    lo, hi = SEALED[name].bounds
    return 0.5 * (lo + hi)


def test_the_sealed_family_is_one_effect_per_locus_apart_from_every_other_name(plant: EmpsPlant) -> None:
    assert set(plant.sealed) == {
        "drive_gain_asymmetry",
        "guide_contamination",
        "screw_load_friction",
        "load_vibration",
        "encoder_slip",
    }
    assert dict(plant.sealed) == SEALED and set(SEALED_FIELDS) == set(SEALED)
    assert not set(SEALED) & set(CATALOGUE)
    assert not set(SEALED) & set(HELD_BACK)
    assert not set(SEALED) & {p.name for p in plant.calibrated}
    assert sorted(e.locus for e in SEALED.values()) == sorted(LOCI)
    for name, e in SEALED.items():
        assert e.name == name and e.description
        assert e.neutral == 0.0 and 0.0 < e.bounds[0] < e.bounds[1] and not e.log
    fields = set(SEALED_FIELDS.values())
    assert fields <= {f.name for f in dataclasses.fields(EmpsParameters)}
    assert not fields & (set(EFFECT_FIELDS.values()) | set(HELD_BACK_FIELDS.values()))


def test_the_sealed_names_are_accepted(plant: EmpsPlant, record: EmpsRecord) -> None:
    for name, field in SEALED_FIELDS.items():
        assert getattr(plant.parameters({name: _sealed_mid(name)}), field) == _sealed_mid(name)
    sim = plant.simulate(record, {name: _sealed_mid(name) for name in SEALED})
    assert set(sim) == set(CHANNEL_NAMES)
    assert all(v.shape == (record.n,) and np.all(np.isfinite(v)) for v in sim.values())
    with pytest.raises(KeyError):
        plant.simulate(record, {"encoder_slips": 1e-6})


def test_neutral_sealed_values_leave_the_model_unchanged_bit_for_bit(
    plant: EmpsPlant, record: EmpsRecord, nominal: dict[str, np.ndarray]
) -> None:
    neutral = {name: e.neutral for name, e in plant.sealed.items()}
    inputs = {"force": np.full(record.n, 1.5), "position": np.full(record.n, 1e-6)}
    for values in ({}, {"stribeck": -8.0, "actuator_delay": 0.0015, "amplifier_dead_band": 0.2}):
        for given in (None, inputs):
            plain = plant.states(record, values, given)
            sealed = plant.states(record, {**values, **neutral}, given)
            for c in CHANNEL_NAMES:
                np.testing.assert_array_equal(sealed[c], plain[c])
    sim = plant.simulate(record, neutral)
    for c in CHANNEL_NAMES:
        np.testing.assert_array_equal(sim[c], nominal[c])


@pytest.mark.parametrize("name", sorted(SEALED))
def test_each_sealed_effect_at_mid_range_changes_a_channel_beyond_the_noise(
    name: str, plant: EmpsPlant, record: EmpsRecord, nominal: dict[str, np.ndarray]
) -> None:
    noise = plant.noise(record)
    sl = plant.scored(record)
    sim = plant.simulate(record, {name: _sealed_mid(name)})
    ratio = {c: float(np.sqrt(np.mean(np.square(sim[c][sl] - nominal[c][sl])))) / noise[c].sigma for c in CHANNEL_NAMES}
    assert max(ratio.values()) > 1.0, ratio


def test_the_floor_vibration_is_a_force_at_the_force_entry(plant: EmpsPlant, record: EmpsRecord) -> None:
    a = 6.0
    vibration = vibration_force(record.t, a)
    assert vibration[0] == 0.0 and np.max(np.abs(vibration)) == pytest.approx(a, rel=1e-3)
    c = np.full(record.n, 2.0)
    for given, schedule in ((None, vibration), ({"force": c}, c + vibration)):
        with_effect = plant.states(record, {"load_vibration": a}, given)
        as_input = plant.states(record, {}, {"force": schedule})
        for ch in CHANNEL_NAMES:
            np.testing.assert_array_equal(with_effect[ch], as_input[ch])


def test_the_encoder_slip_steps_the_recorded_position_only(plant: EmpsPlant, record: EmpsRecord) -> None:
    delta = 5e-6
    plain = plant.states(record, {})
    slipped = plant.states(record, {"encoder_slip": delta})
    for c in ("velocity", "acceleration", "force"):  # the loop is unchanged
        np.testing.assert_array_equal(slipped[c], plain[c])
    step = slipped["position"] - plain["position"]
    after = record.t - record.t[0] >= SLIP_SHARE * (record.t[-1] - record.t[0])
    assert 0.35 < np.mean(after) < 0.65 and not after[0] and after[-1]
    np.testing.assert_array_equal(step[~after], 0.0)
    np.testing.assert_allclose(step[after], delta, rtol=1e-6)


def test_the_contamination_sits_in_the_middle_of_the_shipped_travel(plant: EmpsPlant, record: EmpsRecord) -> None:
    middle = 0.5 * (float(np.min(record.qm)) + float(np.max(record.qm)))
    assert round(middle / 0.005) * 0.005 == pytest.approx(CONTAMINATION_POSITION)


def test_the_drive_gain_asymmetry_keeps_the_force_channel_on_the_command(plant: EmpsPlant, record: EmpsRecord) -> None:
    """More force forward than backward for the same command: the loop commands less forward, more backward."""
    x = plant.states(record, {"drive_gain_asymmetry": 0.1})
    ref = plant.states(record, {})
    sl = plant.scored(record)
    fwd, bwd = ref["force"][sl] > 5.0, ref["force"][sl] < -5.0
    assert np.mean(x["force"][sl][fwd]) < np.mean(ref["force"][sl][fwd])
    assert np.mean(x["force"][sl][bwd]) < np.mean(ref["force"][sl][bwd])
