"""engine.validation.stats.pooled_estimate and bench/pool_identification.py: the inverse-variance pool."""

from __future__ import annotations

import json
import math

import pytest
from bench_scripts import load_bench

from engine.validation.stats import pooled_estimate


def test_the_pool_weights_by_inverse_variance_against_hand_computed_values() -> None:
    two = pooled_estimate([1.0, 3.0], [1.0, 1.0])
    assert two.value == pytest.approx(2.0) and two.stderr == pytest.approx(1 / math.sqrt(2))
    assert two.chi2 == pytest.approx(2.0) and two.dof == 1
    assert two.birge_ratio == pytest.approx(math.sqrt(2.0))  # sqrt(Q / dof)
    assert two.p_value == pytest.approx(0.157299, abs=1e-6)  # chi-square(1) survival at 2
    assert (two.low, two.high) == pytest.approx((2.0 - 1.959964 / math.sqrt(2), 2.0 + 1.959964 / math.sqrt(2)))
    uneven = pooled_estimate([0.0, 10.0], [1.0, 3.0])  # weights 1 and 1/9
    assert uneven.value == pytest.approx(1.0) and uneven.stderr == pytest.approx((10 / 9) ** -0.5)


@pytest.mark.parametrize(
    ("values", "stderrs"),
    [([1.0], [1.0]), ([1.0, 2.0], [1.0]), ([1.0, 2.0], [1.0, 0.0]), ([1.0, math.nan], [1.0, 1.0])],
)
def test_the_pool_refuses_what_it_cannot_weight(values, stderrs) -> None:
    with pytest.raises(ValueError):
        pooled_estimate(values, stderrs)


def test_the_script_pools_the_runs_files_and_refuses_a_file_without_the_paired_figure(tmp_path, capsys) -> None:
    pool = load_bench("pool_identification")
    paths = []
    for i, (v, s) in enumerate(((1.0, 1.0), (3.0, 1.0))):
        paths.append(tmp_path / f"run{i}.json")
        paths[-1].write_text(json.dumps({"paired": {"after_minus_twin": v, "stderr": s}}))
    assert pool.main([str(p) for p in paths]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["pooled"] == 2.0 and out["dof"] == 1
    (tmp_path / "bad.json").write_text(json.dumps({"paired": None}))
    with pytest.raises(SystemExit) as exc:
        pool.main([str(paths[0]), str(tmp_path / "bad.json")])
    assert exc.value.code == 2 and "holds no paired figure" in capsys.readouterr().err
