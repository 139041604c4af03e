"""Coverage of the width's 95 % interval on a blind run (engine.validation.width_coverage)."""

from __future__ import annotations

from pathlib import Path

import pytest

from engine.validation.width_coverage import Truth, coverage, coverage_markdown, truths_from_committed

ROOT = Path(__file__).resolve().parents[1]


def _truth(case: str, K: float, width: dict | None, nominal: tuple[float, float] | None, status: str = "explained"):
    return Truth(case, "single", K, 0.0, status, width, nominal)


def test_coverage_counts_covered_missed_and_not_identifiable_apart() -> None:
    truths = [
        _truth("a", 5e-3, {"identifiable": True, "interval_95": [4.9e-3, 5.1e-3]}, (5.2e-3, 1e-5)),
        _truth("b", 5e-3, {"identifiable": True, "interval_95": [5.01e-3, 5.1e-3]}, (5.0e-3, 1e-5)),
        _truth("c", 5e-3, {"identifiable": False, "interval_95": None, "reason": "misfit"}, None, "unexplained"),
    ]
    rows = {(r.rule, r.group): r for r in coverage(truths)}
    answer = rows[("answer", "all")]
    assert (answer.n, answer.covered, answer.not_identifiable) == (2, 1, 1)
    assert answer.median_half_width_um == pytest.approx(100.0)  # the larger of the two half-widths, 100 um
    nominal = rows[("nominal", "all")]
    assert (nominal.n, nominal.covered, nominal.not_identifiable) == (2, 1, 1)
    assert rows[("answer", "status unexplained")].n == 0
    lo, hi = answer.interval
    assert 0.0 < lo < 0.5 < hi < 1.0
    assert "| answer | all | 2 | 1 |" in coverage_markdown(list(rows.values()), "three cases")


def test_a_rounded_truth_counts_its_rounding() -> None:
    t = Truth(
        "a", "clean", 5.0e-3, 0.5e-6, "no_gap", {"identifiable": True, "interval_95": [5.0004e-3, 5.001e-3]}, None
    )
    (row,) = [r for r in coverage([t]) if (r.rule, r.group) == ("answer", "all")]
    assert row.covered == 1


def test_a_committed_run_is_read_whole() -> None:
    truths = truths_from_committed(ROOT / "docs" / "validation" / "v2-seed229")
    assert len(truths) == 300
    assert {t.kind for t in truths} == {"clean", "single", "pair", "triple", "held_back"}
    assert all(t.width is None for t in truths)  # written before issue 50
    assert sum(t.nominal is not None for t in truths) == 300
    rebuilt = [t for t in truths if t.rule is not None]
    assert 250 < len(rebuilt) < 300  # some unexplained answers' rebuilt widths are not identifiable
    assert all(t.rule is not None for t in truths if t.status == "no_gap")


def test_todays_rule_adds_the_stand_in_term_to_a_weak_explained_answer_written_before_it() -> None:
    from engine.constants import Z95
    from engine.validation.width_coverage import today_rule

    def stored(chi2: float, status: str = "explained") -> dict:
        width = {"K": 5.0e-3, "sigma_K": 2e-6, "identifiable": True, "structure_spread": 0.0, "structure_factor": 4.5}
        return {
            "verdict": {"status": status},
            "calibration": {"reduced_chi2": chi2, "values": {"K": 5.1e-3}, "uncertainties": {"K": 1e-6}},
            "width": width,
        }

    weak = today_rule(stored(4.0))
    assert weak is not None and weak[0] == 5.0e-3
    assert Z95 * weak[1] >= 0.1e-3  # the interval reaches the nominal K, 0.1 mm away
    assert today_rule(stored(400.0)) == pytest.approx((5.0e-3, 2e-6))  # a strong gap: unchanged
    assert today_rule(stored(4.0, "no_gap")) == pytest.approx((5.0e-3, 2e-6))  # no named effect: unchanged
    # an answer that already carries the term is not widened twice
    done = stored(4.0)
    done["width"]["stand_in_reach"] = 0.1e-3
    assert today_rule(done) == pytest.approx((5.0e-3, 2e-6))
