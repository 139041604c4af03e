"""bench/bench_diagnosis_cost.py: the summary of its rows (percentiles, ratios of two codes) and the list of
changed verdicts, on synthetic rows (nothing is diagnosed)."""

from __future__ import annotations

from types import ModuleType
from typing import Any

import pytest
from bench_scripts import load_bench


def load() -> ModuleType:
    return load_bench("bench_diagnosis_cost")


def row(
    case: str, code: str, seconds: float, correct: bool = True, effects: tuple[str, ...] = ("a",)
) -> dict[str, Any]:
    unit = 0.002 if code == "current" else 0.004  # the current code's simulator twice as fast
    return {
        "case": case,
        "group": "single",
        "kind": "single",
        "truth": ["a"],
        "code": code,
        "seconds": seconds,
        "sims": seconds / unit,
        "correct": correct,
        "status": "explained",
        "effects": list(effects),
        "locus": None,
        "n_simulations": 1000,
    }


def test_percentiles_of_each_code_and_their_ratios() -> None:
    mod = load()
    rows = [row(f"c{i}", "current", 1.0 + i) for i in range(40)] + [
        row(f"c{i}", "baseline", 2.0 + 2 * i) for i in range(40)
    ]
    s = mod.summarise(rows, ["single", "compound"], ["current", "baseline"])
    assert set(s) == {"single"}  # a group without rows is left out
    cur, base = s["single"]["current"], s["single"]["baseline"]
    assert (cur["n"], cur["right"], cur["over_target"]) == (40, 40, 30)  # 11 s .. 40 s
    assert cur["seconds"]["p50"]["value"] == pytest.approx(20.5)
    assert cur["seconds"]["p90"]["low"] is not None  # 40 records give the 90th percentile an interval
    assert cur["sims"]["p50"]["value"] == pytest.approx(20.5 / 0.002, rel=1e-3)
    assert base["seconds"]["p50"]["value"] == pytest.approx(41.0)
    r = s["single"]["ratio"]
    assert r["p50_s"] == pytest.approx(0.5, rel=1e-3) and r["per_case_median_s"] == pytest.approx(0.5)
    assert r["p50_sims"] == pytest.approx(1.0, rel=1e-3) and r["per_case_median_sims"] == pytest.approx(1.0)


def test_a_small_sample_has_no_interval_and_the_line_says_so() -> None:
    mod = load()
    rows = [row(f"c{i}", "current", 4.0 + i) for i in range(5)]
    s = mod.summarise(rows, ["single"], ["current"])
    assert s["single"]["current"]["seconds"]["p90"]["low"] is None and "ratio" not in s["single"]
    (line,) = mod.summary_lines(s, ["current"])
    assert "p90 <= 10 s: yes" in line and "n too small for a 95 % interval of p50 and p90" in line


def test_every_changed_verdict_is_listed_with_whether_it_got_better() -> None:
    mod = load()
    rows = [
        row("same", "current", 1.0),
        row("same", "baseline", 1.0),
        row("fixed", "current", 1.0, True, ("a",)),
        row("fixed", "baseline", 1.0, False, ("b",)),
        row("broken", "current", 1.0, False, ("b",)),
        row("broken", "baseline", 1.0, True, ("a",)),
        row("both_wrong", "current", 1.0, False, ("b",)),
        row("both_wrong", "baseline", 1.0, False, ("c",)),
    ]
    changes = {c["case"]: c for c in mod.verdict_changes(rows, ["current", "baseline"])}
    assert {k: c["change"] for k, c in changes.items()} == {
        "fixed": "better",
        "broken": "worse",
        "both_wrong": "same score",
    }
    assert (
        changes["fixed"]["current_verdict"] == "explained a" and changes["fixed"]["baseline_verdict"] == "explained b"
    )
    assert mod.verdict_changes(rows, ["current"]) == []
