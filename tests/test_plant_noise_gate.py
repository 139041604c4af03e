"""Every plant's noise model and the gate it sets (issue 52, item 2): ``no_gap`` and ``weak_gap`` on
records the model already fits, the share rule's answer on records it does not.

Reference data: the shipped BRFD sine test (Rice University's bell-shaped rotational friction
damper, ``engine/plants/brfd/data``) and the EMPS benchmark's DATA_EMPS_PULSES record (Janot,
Gautier, Brunot); synthetic records are simulated on their inputs with each plant's own sensors
(:meth:`~engine.plants.base.Plant.synthesize`), whose noise the truth knows.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from engine.diagnosis.plant_gap import NoiseGate, diagnose_plant
from engine.plants import get_plant
from engine.plants.base import free_parameters
from engine.plants.noise import NOISE_FLOOR_REL, NoiseLevel, white_noise_level
from engine.validation.plant_check import CheckCase, CheckRow, summary


def _perturbed(plant, record, rng: np.random.Generator) -> dict[str, float]:
    """The calibrated parameters within +-10 % of nominal, as the synthetic check draws them."""
    return {
        p.name: float(np.clip(p.nominal * (1.0 + 0.1 * rng.uniform(-1, 1)), p.lo, p.hi))
        for p in free_parameters(plant, record)
    }


def test_the_white_level_is_the_noise_of_a_smooth_signal_and_a_noiseless_channel_gets_the_floor() -> None:
    t = np.linspace(0.0, 1.0, 8192)
    smooth = np.sin(2 * np.pi * 3 * t) + 0.3 * np.sign(np.sin(2 * np.pi * 7 * t))  # with a few edges
    noisy = smooth + np.random.default_rng(0).normal(0.0, 0.02, t.size)
    assert white_noise_level(noisy).sigma == pytest.approx(0.02, rel=0.05)
    assert white_noise_level(noisy).source == "record"
    floor = white_noise_level(smooth)
    assert floor.source == "floor"
    assert floor.sigma == pytest.approx(NOISE_FLOOR_REL * float(np.sqrt(np.mean(smooth**2))))


@pytest.mark.parametrize(
    ("samples", "match"),
    [(np.ones(8), "at least 16"), (np.r_[np.ones(20), np.nan], "finite"), (np.zeros(32), "zero throughout")],
)
def test_a_channel_whose_noise_cannot_be_estimated_is_refused(samples: np.ndarray, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        white_noise_level(samples)
    with pytest.raises(ValueError, match="positive"):
        NoiseLevel(0.0)


def test_the_emps_noise_model_is_the_encoder_noise_a_synthetic_record_carries() -> None:
    """The encoder's quantum through the chain, against the noise a synthetic record really holds."""
    plant = get_plant("emps")
    record = plant.example("DATA_EMPS_PULSES", seconds=4.0)
    rng = np.random.default_rng(7)
    truth = _perturbed(plant, record, rng)
    synthetic = plant.synthesize(record, truth, rng)
    levels = plant.noise(synthetic)
    sl = plant.scored(synthetic)
    sim, meas = plant.simulate(synthetic, truth), plant.measured(synthetic)
    for name in ("position", "velocity", "acceleration"):
        true_sd = float(np.std(meas[name][sl] - sim[name][sl]))
        assert levels[name].source == "encoder quantum"
        assert levels[name].sigma == pytest.approx(true_sd, rel=0.15), name
    assert levels["force"].source == "floor"  # the synthetic command is the simulation's, noiseless


def test_a_clean_brfd_record_is_no_gap_and_a_play_is_named_beyond_the_noise() -> None:
    plant = get_plant("brfd")
    record = plant.example()
    rng = np.random.default_rng(11)
    truth = _perturbed(plant, record, rng)
    clean = diagnose_plant(plant, plant.synthesize(record, truth, rng))
    assert clean.status == "no_gap" and clean.named is None
    assert clean.gate is not None and NoiseGate.fits(clean.gate.before, clean.gate.limits)
    answer = clean.to_dict(plant)
    assert answer["status"] == "no_gap" and answer["verdict"]["effect"] is None
    assert answer["noise"]["levels"]["force"]["source"] == "record"
    assert answer["width"]["identifiable"] is False
    assert set(answer["gap"]) == {"before"}  # nothing named: no "after" to shrink to
    played = diagnose_plant(plant, plant.synthesize(record, {**truth, "backlash": 0.01}, rng))
    assert played.status == "explained" and played.named is not None and played.named.effects[0] == "backlash"
    assert played.gate is not None and played.gate.strength is not None and played.gate.strength > 3.0
    assert played.to_dict(plant)["gap"]["after"]["rms_over_noise"] == pytest.approx(1.0, abs=0.05)


def test_an_effect_too_weak_for_the_noise_is_not_attributed() -> None:
    """A play of 0.2 mm moves the sine test's force by less than 3 noise RMS: ``weak_gap`` or ``no_gap``,
    never a named effect (the rule the backlash drive's verdict follows)."""
    plant = get_plant("brfd")
    record = plant.example()
    rng = np.random.default_rng(12)
    truth = {**_perturbed(plant, record, rng), "backlash": 2e-4}
    report = diagnose_plant(plant, plant.synthesize(record, truth, rng))
    assert report.status in ("no_gap", "weak_gap"), report.gate
    assert report.named is None


def test_a_real_record_is_a_gap_against_its_sensors_noise_and_keeps_the_share_rules_answer() -> None:
    """The real sine test's residual is model error, far above the load cell's noise: the gate says so and
    the answer is the one the share rule gives (``docs/real-data.md``)."""
    plant = get_plant("brfd")
    report = diagnose_plant(plant, plant.example())
    assert report.gate is not None and report.gate.status == "gap"
    assert min(report.gate.before.values()) > 10.0
    assert report.status in ("explained", "partly_explained") and report.named is not None
    assert report.named.effects[0] == "backlash"


def test_the_synthetic_check_counts_false_alarms_on_clean_cases_and_grades_weak_effects() -> None:
    clean = CheckCase(0, None, math.nan, {}, 0.0)
    weak = CheckCase(1, "backlash", 1e-4, {}, 1.0)
    rows = [
        CheckRow(clean, (), None, "no_gap", 0.0, 0.1),
        CheckRow(clean, ("delay",), None, "explained", 0.9, 0.1),
        CheckRow(weak, (), None, "weak_gap", 0.0, 0.1, noise_strength=1.5),
    ]
    assert [r.false_alarm for r in rows] == [False, True, False]
    assert rows[2].weak and rows[2].weak_ok
    text = summary(rows)
    assert "| clean: false alarm (an effect named, or `unexplained`) | clean | 1/2 = 50 % |" in text
    assert "| weak: answered `no_gap`/`weak_gap` or the true effect first | weak, not absorbed | 1/1 = 100 % |" in text


def test_a_clean_emps_record_is_no_gap_through_the_whole_diagnosis() -> None:
    """Four seconds of DATA_EMPS_PULSES' inputs, the rigid model at perturbed parameters, the encoder's
    quantum: the calibration reaches the encoder's noise on every channel and nothing is named."""
    plant = get_plant("emps")
    record = plant.example("DATA_EMPS_PULSES", seconds=4.0)
    rng = np.random.default_rng(13)
    report = diagnose_plant(plant, plant.synthesize(record, _perturbed(plant, record, rng), rng))
    assert report.status == "no_gap", report.gate
    assert report.gate is not None and all(v < 1.2 for v in report.gate.before.values())


def test_a_clean_drive_record_is_no_gap_once_the_calibration_starts_from_the_drives_global_search() -> None:
    """The backlash drive through the plant interface: from the nominal values alone its least squares stopped in
    a local minimum on half of the clean records (seed 25); from its own nominal calibration it reaches the noise."""
    plant = get_plant("backlash_drive")
    record = plant.example()
    rng = np.random.default_rng(14)
    truth = _perturbed(plant, record, rng)
    synthetic = plant.synthesize(record, truth, rng)
    start = plant.calibration_start(synthetic)
    assert start is not None and set(truth) <= set(start)
    report = diagnose_plant(plant, synthetic)
    assert report.status == "no_gap", report.gate
    assert report.calibration.values["K"] == pytest.approx(truth["K"], rel=0.02)
