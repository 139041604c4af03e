"""The helpers the development scripts of ``lab/scripts/`` share (``lab/scripts/_runs.py``) and the argument
checks of ``lab/scripts/case_times.py``."""

from __future__ import annotations

import json

import pytest
from bench_scripts import load_bench

from engine.diagnosis.diagnose import DiagnosisSettings


def test_settings_are_updated_field_by_field_and_a_dict_updates_a_nested_dataclass() -> None:
    runs = load_bench("_runs")
    ds = DiagnosisSettings()
    new = runs.updated(ds, {"sets": {"escalate_before_reseed": False}, "locate": False})
    assert new.sets.escalate_before_reseed is False and new.locate is False
    assert new.sets.n_escalate_first == ds.sets.n_escalate_first  # the rest of the nested settings stay
    assert ds.sets.escalate_before_reseed is True  # the original is not changed
    with pytest.raises(TypeError, match="no field no_such_field"):
        runs.updated(ds, {"no_such_field": 1})
    with pytest.raises(TypeError, match="JSON object"):
        runs.updated(ds, [1])


def test_case_times_refuses_two_baselines_and_settings_it_does_not_know(tmp_path, capsys) -> None:
    case_times = load_bench("case_times")
    for extra, message in (
        (["--baseline-threads", "1", "--baseline-sets", "{}"], "not both"),
        (["--baseline-sets", '{"no_such_field": 1}'], "--baseline-sets"),
    ):
        with pytest.raises(SystemExit) as exc:
            case_times.main([str(tmp_path), *extra])
        assert exc.value.code == 2 and message in capsys.readouterr().err


def test_v1_case_times_refuses_a_run_without_its_report_or_cases_of_the_kind(tmp_path, capsys) -> None:
    v1 = load_bench("v1_case_times")
    with pytest.raises(SystemExit) as exc:
        v1.main([str(tmp_path)])
    assert exc.value.code == 2 and "report.json is missing" in capsys.readouterr().err
    (tmp_path / "report.json").write_text(json.dumps({"per_case": [{"case_id": "case0000", "expected": "no_gap"}]}))
    with pytest.raises(SystemExit) as exc:
        v1.main([str(tmp_path), "--expected", "unexplained"])
    assert exc.value.code == 2 and "no case whose expected answer is unexplained" in capsys.readouterr().err


def test_v1_case_times_takes_the_first_cases_of_the_kind_in_id_order(tmp_path, capsys, monkeypatch) -> None:
    """The cases are chosen by kind and id only (never by outcome), each diagnosed once, and summarised."""
    v1 = load_bench("v1_case_times")
    rows = [
        {"case_id": f"case{i:04d}", "expected": e, "status": "unexplained", "seconds": 10.0 * (i + 1)}
        for i, e in enumerate(["unexplained", "no_gap", "unexplained", "unexplained", "unexplained"])
    ]
    (tmp_path / "report.json").write_text(json.dumps({"per_case": rows[::-1]}))  # the report's order is not used
    (tmp_path / "cases").mkdir()
    for r in rows:
        (tmp_path / "cases" / f"{r['case_id']}.json").write_text("{}")
    seen: list[str] = []
    monkeypatch.setattr(v1.BlindCase, "from_dict", classmethod(lambda cls, d: d))
    monkeypatch.setattr(
        v1, "_diagnose_case", lambda case, settings: seen.append("x") or {"verdict": {"status": "unexplained"}}
    )
    assert v1.main([str(tmp_path), "--expected", "unexplained", "--n", "3", "--budget", "1e9"]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [line["case_id"] for line in lines[:-1]] == ["case0000", "case0002", "case0003"]
    assert [line["run_seconds"] for line in lines[:-1]] == [10.0, 30.0, 40.0]
    summary = lines[-1]
    assert len(seen) == 3 and summary["n"] == 3 and summary["expected"] == "unexplained"
    assert summary["over_1e+09_s"] == 0 and summary["median"][0] is not None


def test_v1_case_times_refuses_a_protocol_2_report(tmp_path, capsys) -> None:
    v1 = load_bench("v1_case_times")
    (tmp_path / "report.json").write_text(json.dumps({"protocol": 2, "cases": []}))
    with pytest.raises(SystemExit) as exc:
        v1.main([str(tmp_path)])
    assert exc.value.code == 2 and "not a protocol-1 report" in capsys.readouterr().err


def test_v1_case_times_run_times_summarise_the_report_without_diagnosing(tmp_path, capsys, monkeypatch) -> None:
    v1 = load_bench("v1_case_times")
    rows = [{"case_id": f"case{i:04d}", "expected": "explained", "seconds": s} for i, s in enumerate((5.0, 40.0, 7.0))]
    (tmp_path / "report.json").write_text(json.dumps({"per_case": rows}))
    monkeypatch.setattr(v1, "_diagnose_case", lambda case, settings: pytest.fail("nothing is diagnosed"))
    assert v1.main([str(tmp_path), "--run-times"]) == 0
    (line,) = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert line == {"expected": "explained", "n": 3, "median": 7.0, "max": 40.0, "over_30_s": 1}
