"""Protocol 1's blind run is resumable: an interrupted run keeps its cases and diagnoses and does the rest."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest

from engine.diagnosis import validation as v1
from engine.diagnosis.diagnose import DiagnosisSettings
from engine.validation.run import run_validation as run_v2

MIX = {"effect": 0.5, "left_out": 0.25, "clean": 0.25}
CALLS: list[str] = []
INTERRUPT_AT = [0]


def fake_diagnosis(case: v1.BlindCase, settings: DiagnosisSettings) -> dict[str, Any]:
    """A cheap stand-in of one case's diagnosis (answers no_gap); raises KeyboardInterrupt at call INTERRUPT_AT."""
    CALLS.append(case.case_id)
    if len(CALLS) == INTERRUPT_AT[0]:
        raise KeyboardInterrupt
    return {
        "verdict": {"status": "no_gap", "effect": None, "value": None, "confidence": 1.0, "reason": "stand-in"},
        "candidates": [],
        "ranking": [],
        "case_id": case.case_id,
        "wall_seconds": 0.0,
    }


@pytest.fixture(autouse=True)
def _reset() -> None:
    CALLS.clear()
    INTERRUPT_AT[0] = 0


def test_an_interrupted_run_resumes_where_it_stopped(tmp_path: Path) -> None:
    out = tmp_path / "run"
    INTERRUPT_AT[0] = 3
    with pytest.raises(KeyboardInterrupt):
        v1.run_validation(4, 5, out, fractions=MIX, diagnose_fn=fake_diagnosis)
    assert CALLS == ["case0000", "case0001", "case0002"]
    done = sorted(p.name for p in (out / "results").iterdir())
    assert done == ["case0000.json", "case0001.json"]  # the interrupted case left no file, not even a partial one
    manifest = json.loads((out / v1.MANIFEST).read_text())
    assert manifest["complete"] and manifest["protocol"] == 1 and manifest["seed"] == 5
    kept = {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in (out / "cases").iterdir()}
    first = (out / "results" / "case0000.json").stat().st_mtime_ns
    assert not (out / "report.json").exists()

    CALLS.clear()
    INTERRUPT_AT[0] = 0
    report = v1.run_validation(4, 5, out, fractions=MIX, diagnose_fn=fake_diagnosis)
    assert CALLS == ["case0002", "case0003"]  # only the cases without a result
    assert {p.name: (p.read_bytes(), p.stat().st_mtime_ns) for p in (out / "cases").iterdir()} == kept
    assert (out / "results" / "case0000.json").stat().st_mtime_ns == first
    assert report.n_cases == 4 and (out / "report.json").exists() and (out / "report.md").exists()
    # and the same run from scratch scores the same
    fresh = v1.run_validation(4, 5, tmp_path / "fresh", fractions=MIX, diagnose_fn=fake_diagnosis)
    assert fresh.to_dict() == report.to_dict()


def test_a_run_with_other_settings_is_refused_and_left_as_it_was(tmp_path: Path) -> None:
    out = tmp_path / "run"
    v1.run_validation(3, 5, out, fractions=MIX, diagnose_fn=fake_diagnosis)
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    for kwargs in ({"n_cases": 3, "seed": 6}, {"n_cases": 4, "seed": 5}):
        with pytest.raises(
            FileExistsError, match=re.escape("holds another validation run (protocol 1, seed 5, 3 cases)")
        ):
            v1.run_validation(out_dir=out, fractions=MIX, diagnose_fn=fake_diagnosis, **kwargs)
    with pytest.raises(FileExistsError, match=re.escape("holds another validation run (protocol 1,")):
        v1.run_validation(3, 5, out, fractions={"effect": 1.0}, diagnose_fn=fake_diagnosis)
    # protocol 2 refuses it too, naming it
    with pytest.raises(FileExistsError, match="protocol 1"):
        run_v2(3, 5, out)
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


def test_a_directory_without_a_manifest_is_refused(tmp_path: Path) -> None:
    """Cases or results without run.json (a run of before the manifest, or foreign files) are never mixed in."""
    out = tmp_path / "run"
    (out / "results").mkdir(parents=True)
    (out / "results" / "case0000.json").write_text("{}")
    with pytest.raises(FileExistsError, match="without a manifest"):
        v1.run_validation(2, 5, out, fractions=MIX, diagnose_fn=fake_diagnosis)
    assert sorted(p.name for p in out.rglob("*")) == ["case0000.json", "results"]
    assert CALLS == []


@pytest.mark.parametrize("content", ["{not json", "[1, 2]", "\udcff"])
def test_a_damaged_manifest_is_refused_by_either_protocol_and_left_as_it_was(tmp_path: Path, content: str) -> None:
    """A run.json that is not a JSON object is neither taken for a run of ours nor overwritten."""
    out = tmp_path / "run"
    out.mkdir()
    (out / "run.json").write_bytes(content.encode("utf-8", "surrogateescape"))
    before = (out / "run.json").read_bytes()
    with pytest.raises(FileExistsError, match="is not a run manifest"):
        v1.run_validation(2, 5, out, fractions=MIX, diagnose_fn=fake_diagnosis)
    with pytest.raises(FileExistsError, match="is not a run manifest"):
        run_v2(2, 5, out)
    assert (out / "run.json").read_bytes() == before and [p.name for p in out.iterdir()] == ["run.json"]
    assert CALLS == []
