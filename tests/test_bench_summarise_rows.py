"""lab/scripts/summarise_rows.py: the summary that reproduces the time and accuracy figures of the rows in lab/validation/."""

from __future__ import annotations

import json
from pathlib import Path
from types import ModuleType

import pytest
from bench_scripts import load_bench


def load() -> ModuleType:
    return load_bench("summarise_rows")


def write(path: Path, rows: list[dict]) -> Path:
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    return path


def test_a_later_row_of_the_same_case_replaces_the_earlier_one(tmp_path: Path) -> None:
    mod = load()
    base = write(
        tmp_path / "base.jsonl",
        [{"case": f"c{i}", "kind": "triple", "correct": i != 0, "seconds": 10.0 + i} for i in range(20)]
        + [{"case": "s0", "kind": "single", "correct": True, "seconds": 12.0}],
    )
    lever = write(tmp_path / "lever.jsonl", [{"case": "c0", "kind": "triple", "correct": True, "seconds": 99.0}])
    rows = mod.read_rows([base, lever])
    assert len(rows) == 21 and rows["c0"]["seconds"] == 99.0
    compound = mod.summarise(rows, ("pair", "triple"), 60.0)
    assert (compound["n"], compound["right"], compound["over_budget"]) == (20, 20, 1)
    assert compound["median_s"] == pytest.approx(20.5)  # 11..29 and 99
    single = mod.summarise(rows, ("single",), 10.0)
    assert (single["n"], single["over_budget"]) == (1, 1)
    assert mod.summarise(rows, ("held_back",), None) == {"n": 0}


@pytest.mark.parametrize(
    ("line", "message"),
    [("not json", "not a JSON row"), ('{"case": "c1", "kind": "pair"}', "has no correct, seconds")],
)
def test_a_row_it_cannot_read_is_refused_with_its_file_and_line(tmp_path: Path, line: str, message: str) -> None:
    mod = load()
    path = tmp_path / "rows.jsonl"
    path.write_text(json.dumps({"case": "c0", "kind": "pair", "correct": True, "seconds": 1.0}) + "\n" + line + "\n")
    with pytest.raises(ValueError, match=rf"rows.jsonl:2: .*{message}"):
        mod.read_rows([path])


def test_every_true_effect_named_counts_a_set_that_holds_the_truth_and_twins_as_the_scorer_does() -> None:
    rows = load_bench("summarise_rows")
    base = {"kind": "pair", "truth": ["load_inertia", "measurement_delay"], "correct": False, "seconds": 1.0}
    more = {
        **base,
        "status": "explained",
        "effects": ["load_inertia", "trigger_offset", "sensor_gain"],
        "alternatives": [[], ["measurement_delay"], []],
    }
    assert rows.all_true_named(more) is True  # a twin named for the delay, one effect more
    assert rows.all_true_named({**more, "alternatives": [[], [], []]}) is False
    assert rows.all_true_named({**more, "status": "unexplained"}) is False
    assert rows.all_true_named(base) is None  # no answer in the row: not counted
