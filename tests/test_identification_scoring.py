"""The identification scorer's bookkeeping: the splits and their paired differences, with a faked identifier.

The real identifier and simulator run in ``tests/test_diagnosis.py::test_small_blind_validation``
(slow); here the identifier is replaced so that every split's hits are known in advance.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bench_scripts import load_bench

from engine.constants import K_GRID
from engine.evaluation import identification as scoring
from engine.records import Record

RIGHT, WRONG = K_GRID[2], K_GRID[4]
TRUE_VALUE = 0.9


def _record(twin: bool = False) -> Record:
    x = np.linspace(0.0, 1.0, 400) - (1.0 if twin else 0.0)  # a twin is told by its first sample, -1
    return Record({"a1": x, "m_el": x}, 1e-3, 10)


def _fake_identify(
    record: Record, effect: str | None, value: float | None, c: float, kind: str, at_groups: bool
) -> dict[str, Any]:
    """Known answers: twins right on both channels; nominal patterns on an effect record wrong on both;
    patterns of the true effect at its true value right on a1 only; any other patterns wrong on both."""
    twin = record.channels["a1"][0] == -1.0
    before = RIGHT if twin else WRONG
    channels = {}
    for ch in record.channels:
        after = None
        if effect is not None:
            exact = effect == "supply_voltage" and value == TRUE_VALUE
            after = {"width": RIGHT if exact and ch == "a1" else WRONG}
        channels[ch] = {"before": {"width": before}, "after": after}
    return {"channels": channels}


def _write_run(out: Path) -> None:
    (out / "key").mkdir(parents=True)
    (out / "cases").mkdir()
    (out / "results").mkdir()
    key = [
        {"case_id": "case0", "kind": "effect", "expected_status": "explained", "effect": "supply_voltage",
         "value": TRUE_VALUE, "K": RIGHT},
        {"case_id": "case1", "kind": "effect", "expected_status": "explained", "effect": "supply_voltage",
         "value": TRUE_VALUE, "K": RIGHT},
        {"case_id": "case2", "kind": "clean", "expected_status": "no_gap", "effect": None, "value": None, "K": RIGHT},
    ]  # fmt: skip
    (out / "key" / "answer_key.json").write_text(json.dumps(key))
    named = {"case0": ("supply_voltage", TRUE_VALUE), "case1": ("rotor_resistance_drift", 1.05), "case2": None}
    for cid, fix in named.items():
        (out / "cases" / f"{cid}.json").write_text(json.dumps({"record": _record().to_dict()}))
        verdict = {"status": "explained", "effect": fix[0], "value": fix[1]} if fix else {"status": "no_gap"}
        result = {"verdict": verdict, "calibration": {"values": {"c": 1.0}, "fixed": {}}}
        (out / "results" / f"{cid}.json").write_text(json.dumps(result))


def test_the_oracle_split_separates_the_diagnosis_share_from_the_identifier_share(tmp_path, monkeypatch):
    _write_run(tmp_path)
    monkeypatch.setattr(scoring, "identify_before_after", _fake_identify)
    monkeypatch.setattr(scoring, "clean_twins", lambda truths, records: [_record(twin=True) for _ in records])
    got = scoring.score_identification(tmp_path)
    acc, n = got["accuracy"], got["n"]
    assert n == {"clean": 1, "twin": 2, "before": 2, "after": 2, "oracle": 2}
    assert acc["twin"]["mean"] == 1.0 and acc["before"]["mean"] == 0.0
    # case0 is named right at the true value (after = oracle: a1 right), case1 wrong (after: both wrong)
    assert acc["oracle"] == pytest.approx({"a1": 1.0, "m_el": 0.0, "mean": 0.5})
    assert acc["after"] == pytest.approx({"a1": 0.5, "m_el": 0.0, "mean": 0.25})
    p = got["paired"]
    assert p["after_minus_twin"] == pytest.approx(-75.0)
    assert p["after_minus_oracle"] == pytest.approx(-25.0)
    assert p["oracle_minus_twin"] == pytest.approx(-50.0)
    # per case (after - oracle) is 0 and -50 points: standard error 25
    assert p["after_minus_oracle_stderr"] == pytest.approx(25.0)
    assert got["by_effect"] == {
        "supply_voltage": {"n": 2, "after_minus_twin": pytest.approx(-75.0), "oracle_minus_twin": pytest.approx(-50.0)}
    }
    text = scoring.identification_markdown(got)
    assert "true effect at its true value" in text and "diagnosis's share" in text and "| supply_voltage | 2 |" in text


def test_the_rescoring_script_writes_beside_the_run_never_into_it(tmp_path, monkeypatch, caplog):
    script = load_bench("rescore_identification")
    run = tmp_path / "run"
    _write_run(run)
    monkeypatch.setattr(scoring, "identify_before_after", _fake_identify)
    monkeypatch.setattr(scoring, "clean_twins", lambda truths, records: [_record(twin=True) for _ in records])
    assert script.main([str(run), "--to", str(run)]) == 2
    assert "must not be the run itself" in caplog.text and not (run / "identification.md").exists()
    assert script.main([str(tmp_path / "nothing"), "--to", str(tmp_path / "x")]) == 2
    assert "not a finished protocol-1 run" in caplog.text and not (tmp_path / "x").exists()
    v2 = tmp_path / "v2"
    _write_run(v2)
    (v2 / "key" / "answer_key.json").write_text(json.dumps({"protocol": 2, "cases": []}))
    assert script.main([str(v2), "--to", str(tmp_path / "y")]) == 2
    assert "not a protocol-1 run" in caplog.text and not (tmp_path / "y").exists()
    assert script.main([str(run), "--to", str(tmp_path / "again")]) == 0
    stored = json.loads((tmp_path / "again" / "identification.json").read_text())
    assert stored["paired"]["after_minus_oracle"] == pytest.approx(-25.0)
    assert (tmp_path / "again" / "identification.md").read_text().startswith("| split |")
