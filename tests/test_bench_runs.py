"""The helpers the development scripts of ``bench/`` share (``bench/_runs.py``) and the argument
checks of ``bench/case_times.py``."""

from __future__ import annotations

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
