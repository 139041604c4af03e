"""Per-case row files (engine.validation.rows): case rows read, summary lines left out, bad lines named."""

from __future__ import annotations

from pathlib import Path

import pytest

from engine.validation.rows import json_rows


def test_case_rows_are_read_and_the_summary_line_left_out(tmp_path: Path) -> None:
    f = tmp_path / "rows.jsonl"
    f.write_text('{"case": "c0", "right": true}\n\n{"case": "c1", "right": false}\n{"summary": "1/2"}\n')
    assert [(i, r["case"]) for i, r in json_rows(f, ("right",))] == [(1, "c0"), (3, "c1")]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('{"case": "c0", "right": true}\nnot json\n', "rows.jsonl:2: not a JSON row"),
        ("[1, 2]\n", "rows.jsonl:1: not a JSON object"),
        ('{"case": "c0"}\n', "rows.jsonl:1: the row has no right"),
    ],
)
def test_a_line_that_cannot_be_read_is_named(tmp_path: Path, text: str, message: str) -> None:
    f = tmp_path / "rows.jsonl"
    f.write_text(text)
    with pytest.raises(ValueError, match=message):
        list(json_rows(f, ("right",)))
