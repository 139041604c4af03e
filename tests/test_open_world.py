"""The open-world part of the confidence: how likely an explained answer is a catalogue stand-in."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from engine.diagnosis.confidence import calibrated_confidence, load_map, stand_in_probability
from engine.diagnosis.diagnose import DiagnosisSettings, decide
from engine.diagnosis.open_world import (
    OPEN_WORLD_EDGES,
    STAND_IN_WARN,
    OpenWorldMap,
    fit_open_world,
    stand_in_doubt,
    stand_in_warnings,
)
from engine.diagnosis.result import Verdict
from tests.test_sets import fake_cal, single

ROOT = Path(__file__).resolve().parents[1]


def test_fit_counts_explained_answers_per_band_of_all_records_of_each_kind():
    inside = [(2.0, True), (3.0, False), (50.0, True), (500.0, True)]
    outside = [(4.0, True), (5.0, True), (60.0, False)]
    world = fit_open_world(inside, outside, edges=(10.0,), share=0.5)
    assert world.explained_in == ((1, 4), (2, 4)) and world.explained_out == ((2, 3), (0, 3))
    # Bayes' rule with Beta(1/2, 1/2) rates: weak band out 2.5/4, in 1.5/5
    p_out, p_in = 2.5 / 4, 1.5 / 5
    assert world.stand_in(5.0) == pytest.approx(p_out / (p_out + p_in))
    assert world.stand_in(10.0) == world.stand_in(1e6) < world.stand_in(9.99)
    assert OpenWorldMap.from_dict(world.to_dict()) == world
    with pytest.raises(ValueError):
        world.stand_in(math.nan)
    with pytest.raises(ValueError):
        fit_open_world(inside, [], edges=(10.0,))  # no record outside the catalogue
    with pytest.raises(ValueError):
        OpenWorldMap((10.0,), ((1, 4),), ((0, 3), (0, 3)))  # one band's count missing


def test_committed_map_doubts_weak_gaps_and_names_its_spent_families():
    cmap = load_map()
    world = cmap.open_world
    assert world is not None and world.edges == OPEN_WORLD_EDGES
    fitted = {r["run"] for r in cmap.provenance["open_world_fitted_on"]}
    # development data only: families whose blind figures are spent, none of the held-out runs
    assert fitted == {"v2-heldout-seed241", "v2-sealed-seed257"}
    assert not fitted & set(cmap.provenance["held_out"])
    assert all((ROOT / "docs" / "validation" / r).is_dir() for r in fitted)
    weak, strong = stand_in_probability(4.0, cmap), stand_in_probability(400.0, cmap)
    assert weak is not None and strong is not None
    assert weak >= STAND_IN_WARN > strong
    # an explained verdict's probability carries it; other statuses do not
    assert calibrated_confidence("explained", 0.9, cmap, 4.0) == pytest.approx(
        calibrated_confidence("explained", 0.9, cmap) * (1 - weak)
    )
    assert calibrated_confidence("unexplained", 0.9, cmap, 4.0) == calibrated_confidence("unexplained", 0.9, cmap)


def test_decide_states_less_for_the_same_fit_at_a_weak_gap():
    s = DiagnosisSettings()
    best = single("rotor_resistance_drift", 1.0, 30.0)
    weak = decide(fake_cal(4.0, k=4), [best], s)
    strong = decide(fake_cal(400.0, k=4), [best], s)
    assert weak.status == strong.status == "explained"
    assert weak.score == pytest.approx(strong.score)
    assert weak.confidence < 0.7 < 0.9 < strong.confidence


def test_stand_in_warning_names_the_effect_and_what_to_check():
    world = load_map().open_world
    assert world is not None
    row = {"effect": "rotor_resistance_drift", "value": 0.9282, "uncertainty": 0.001, "unit": "x"}
    v = Verdict("explained", "rotor_resistance_drift", 0.9282, 0.001, "x", 0.5, "r", effects=[row])
    (w,) = stand_in_warnings(v, 4.0, stand_in_doubt(v.status, 4.0, world))
    assert w.code == "stand_in" and "rotor_resistance_drift = 0.9282 x" in w.message
    assert "chi2/n = 4" in w.message and "stronger excitation" in w.message
    assert stand_in_warnings(v, 400.0, stand_in_doubt(v.status, 400.0, world)) == []  # a strong gap: no warning
    assert stand_in_warnings(v, 4.0, stand_in_doubt(v.status, 4.0, None)) == []  # no map part: no warning
    other = Verdict.without_effect("unexplained", 0.9, "r")
    assert stand_in_warnings(other, 4.0, stand_in_doubt(other.status, 4.0, world)) == []


def test_explained_by_gap_keeps_the_kinds_asked_and_the_outcomes_with_a_nominal_fit():
    from engine.validation.reliability import IN_CATALOGUE_KINDS, CaseOutcome, explained_by_gap

    def outcome(kind: str, status: str, chi2: float | None) -> CaseOutcome:
        return CaseOutcome("r", 2, "c", kind, status, 0.9, 0.9, True, (), None, None, None, chi2)

    rows = [
        outcome("single", "explained", 4.0),
        outcome("held_back", "explained", 3.0),
        outcome("pair", "no_gap", None),
    ]
    assert explained_by_gap(rows, IN_CATALOGUE_KINDS) == [(4.0, True)]
    assert explained_by_gap(rows) == [(4.0, True), (3.0, True)]
