"""engine/atomic.py: files written whole or not at all, with the mode of a plain write."""

from __future__ import annotations

import json
import math
import stat
from pathlib import Path

import pytest

from engine.atomic import write_json_atomic, write_text_atomic


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def test_the_file_gets_the_mode_of_a_plain_write_and_no_temporary_file_is_left(tmp_path) -> None:
    plain = tmp_path / "plain.txt"
    plain.write_text("x")
    target = tmp_path / "a.json"
    write_json_atomic(target, {"a": 1}, indent=1)
    assert json.loads(target.read_text()) == {"a": 1}
    assert _mode(target) == _mode(plain)  # not mkstemp's 0o600
    write_text_atomic(target, "second")  # replaced whole
    assert target.read_text() == "second" and _mode(target) == _mode(plain)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "plain.txt"]


def test_a_failed_write_leaves_the_old_file_and_no_temporary_file(tmp_path) -> None:
    target = tmp_path / "r.json"
    write_json_atomic(target, {"kept": True})
    with pytest.raises(ValueError):
        write_json_atomic(target, {"bad": math.nan})  # refused before anything is written
    with pytest.raises(TypeError):
        write_text_atomic(target, 3)  # type: ignore[arg-type]  # fails inside the write
    assert json.loads(target.read_text()) == {"kept": True}
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]
