"""The locus estimate through the plant interface (:mod:`engine.diagnosis.plant_locus`, issue 52 item 2).

Synthetic BRFD records (the shipped 1 Hz sine test's displacement, the plant's own noise) with one
effect of the plant's held-back family, outside its catalogue: the answer must name no catalogue set
and must say which part of the damper the missing term acts at. The values are fixed, mid-range.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from engine.diagnosis.plant_gap import diagnose_plant
from engine.diagnosis.plant_locus import N_HATS, estimate_plant_locus, signal_basis
from engine.plants import get_plant
from engine.plants.base import LocusSignal

TRUTH = {"Fc": 8600.0, "sigma0": 1.1e7}


@pytest.fixture(scope="module")
def brfd():  # type: ignore[no-untyped-def]
    plant = get_plant("brfd")
    return plant, plant.example()


@pytest.mark.parametrize(
    ("effect", "value"),
    [("linkage_return_spring", 1.2e5), ("band_relaxation", 0.45), ("load_cell_drift", 220.0)],
)
def test_a_held_back_effect_is_unexplained_at_its_own_locus(brfd, effect: str, value: float) -> None:  # type: ignore[no-untyped-def]
    plant, record = brfd
    synthetic = plant.synthesize(record, {**TRUTH, effect: value}, np.random.default_rng(5))
    report = diagnose_plant(plant, synthetic)
    answer = report.to_dict(plant)
    assert answer["status"] == "unexplained", answer["verdict"]
    assert answer["verdict"]["effects"] == []
    assert answer["verdict"]["locus"] == plant.held_back[effect].locus
    assert answer["verdict"]["locus_confidence"] > 0.9
    assert answer["locus"]["scores"][plant.held_back[effect].locus]["explained"] > 0.5
    assert answer["locus"]["term"]["description"]
    json.dumps(answer)  # the answer is JSON as it stands


def test_an_effect_the_calibration_absorbs_to_a_weak_gap_still_gets_its_locus(brfd) -> None:  # type: ignore[no-untyped-def]
    """A friction fade: the refitted friction level takes most of it, the misfit left is a few noise
    RMS (``weak_gap``, nothing attributed), and the answer says where it acts, as the drive's weak gaps do."""
    plant, record = brfd
    report = diagnose_plant(plant, plant.synthesize(record, {**TRUTH, "friction_fade": 0.25}, np.random.default_rng(7)))
    answer = report.to_dict(plant)
    assert answer["status"] == "weak_gap", answer["verdict"]
    assert answer["verdict"]["effects"] == []
    assert answer["verdict"]["locus"] == plant.held_back["friction_fade"].locus
    assert answer["locus"] is not None and answer["verdict"]["locus_confidence"] is not None


def test_a_catalogue_effect_is_still_named_and_a_clean_record_runs_no_locus(brfd) -> None:  # type: ignore[no-untyped-def]
    plant, record = brfd
    rng = np.random.default_rng(6)
    named = diagnose_plant(plant, plant.synthesize(record, {**TRUTH, "asymmetric_friction": 0.3}, rng))
    assert named.status == "explained" and named.named is not None
    assert named.named.effects[0] == "asymmetric_friction"
    assert named.to_dict(plant)["verdict"]["locus"] == "brake"
    clean = diagnose_plant(plant, plant.synthesize(record, TRUTH, rng))
    assert clean.status == "no_gap" and clean.locus is None


def test_the_real_sine_test_keeps_the_catalogues_answer_and_its_remaining_locus_is_a_first_guess(brfd) -> None:  # type: ignore[no-untyped-def]
    """Model error far above the noise is no evidence against the catalogue: the share rule's answer
    stands, and the locus of what it leaves is capped as a first guess."""
    plant, record = brfd
    report = diagnose_plant(plant, record)
    assert report.named is not None and "backlash" in report.named.effects
    assert report.locus is not None and report.locus.locus is not None
    assert report.locus.confidence <= 0.5 and "first guess" in report.locus.note


def test_threads_change_no_answer(brfd) -> None:  # type: ignore[no-untyped-def]
    """The simulation pool (issue 54) runs the fits' independent simulations, the candidates' fits and
    the locus's stages on threads: the answer must be the one a single thread gives, field by field."""
    plant, record = brfd
    threaded = type(plant)()
    threaded.concurrent = True  # the BRFD runs on one thread by default (its simulations are short)
    synthetic = plant.synthesize(record, {**TRUTH, "band_relaxation": 0.45}, np.random.default_rng(5))

    def answer(jobs: int) -> dict:  # type: ignore[type-arg]
        out = diagnose_plant(threaded, synthetic, jobs=jobs).to_dict(threaded)
        out.pop("n_simulations")  # evaluations a thread's cache misses are counted, not the answer
        out["locus"].pop("n_simulations")
        return out

    one = answer(1)
    assert one["status"] == "unexplained" and one["locus"] is not None
    assert answer(2) == one


def test_a_plant_without_locus_signals_is_refused() -> None:
    plant = get_plant("backlash_drive")
    record = plant.example()
    with pytest.raises(ValueError, match="no locus signals"):
        estimate_plant_locus(plant, record, {})


def test_the_bases_are_hats_over_the_signals_range_times_its_factor_or_harmonics_of_its_period() -> None:
    s = np.linspace(-1.0, 1.0, 201)
    factor = np.where(s > 0, 2.0, -1.0)
    basis, knots, penalty = signal_basis(LocusSignal("x", "force", "s", "m", s, factor), slice(None))
    assert basis.shape == (201, N_HATS) and knots is not None and knots.size == N_HATS
    np.testing.assert_allclose(basis.sum(axis=1), factor)  # hats sum to one
    assert penalty.shape == (N_HATS, N_HATS) and np.allclose(penalty @ np.ones(N_HATS), 0.0)  # a constant is smooth
    periodic, none, eye = signal_basis(LocusSignal("x", "force", "angle", "m", s, period=0.5), slice(None))
    assert none is None and periodic.shape[1] == eye.shape[0]
    np.testing.assert_allclose(periodic[:, 0], np.cos(2.0 * math.pi * s / 0.5))


def test_the_brfd_takes_inputs_at_its_entries_and_refuses_others(brfd) -> None:  # type: ignore[no-untyped-def]
    plant, record = brfd
    base = plant.simulate(record, TRUTH)["force"]
    bump = plant.simulate(record, TRUTH, {"force": np.full(record.n, 100.0)})["force"]
    np.testing.assert_allclose(bump - base, 100.0)
    with pytest.raises(KeyError, match="entries"):
        plant.simulate(record, TRUTH, {"torque": np.zeros(record.n)})
    with pytest.raises(ValueError, match="finite samples"):
        plant.simulate(record, TRUTH, {"displacement": np.zeros(3)})
    families = {**plant.held_back, **plant.sealed}
    assert len(families) == len(plant.held_back) + len(plant.sealed)  # no name in both
    sl = plant.scored(record)
    noise = 0.02 * float(np.sqrt(np.mean(base**2)))  # the synthetic records' noise (model.SYNTHETIC_NOISE_SHARE)
    for name, e in families.items():  # accepted by name; neutral is the model unchanged; mid-range shows
        neutral = plant.simulate(record, {**TRUTH, name: e.neutral})["force"]
        np.testing.assert_array_equal(neutral, base)
        assert name not in plant.catalogue
        mid = plant.simulate(record, {**TRUTH, name: 0.5 * sum(e.bounds)})["force"]
        assert float(np.sqrt(np.mean((mid - base)[sl] ** 2))) > 2.0 * noise, name
    assert {e.locus for e in plant.held_back.values()} == {e.locus for e in plant.sealed.values()} == set(plant.loci)


def test_the_synthetic_check_scores_a_held_back_effect_by_the_answers_locus_apart_from_the_catalogues() -> None:
    from engine.validation.plant_check import CheckCase, CheckRow, measures

    spring = CheckCase(0, "linkage_return_spring", 1e5, {}, 20.0, True, "linkage")
    drift = CheckCase(1, "load_cell_drift", 50.0, {}, 2.0, True, "sensors")
    rows = [
        CheckRow(spring, (), None, "unexplained", 0.0, 0.1, noise_strength=8.0, locus="linkage"),
        CheckRow(spring, ("self_energizing",), None, "explained", 0.95, 0.1, noise_strength=8.0, locus="band"),
        CheckRow(drift, (), None, "weak_gap", 0.0, 0.1, noise_strength=1.0),
    ]
    by_key = {m.key: (m.k, m.n) for m in measures(rows)}
    assert by_key["held_back_locus"] == (1, 2)
    assert by_key["held_back_abstained"] == (1, 2)
    assert by_key["held_back_weak_ok"] == (1, 1)
    assert "top1" not in by_key  # held-back cases are not catalogue cases: no catalogue rate is drawn from them
