"""lab/scripts/quantum_flips.py: the rounded model's samples in the wrong cell, on simulated records."""

from __future__ import annotations

from types import ModuleType

import pytest
from bench_scripts import load_bench

from engine.simulation import PlantParameters, simulate
from engine.simulation.parameters import SolverSettings

PLANT = PlantParameters(K=0.007, J1=0.95, c=1.3)
Q = 0.3


def load() -> ModuleType:
    return load_bench("quantum_flips")


def model(load_inertia: float) -> dict:
    """A stored model of load inertia + quantum, as a result's candidate holds it (K, J1 and c are the
    record's known conditions)."""
    values = {"load_inertia": load_inertia, "speed_quantization": Q}
    return {
        "names": ["load_inertia", "speed_quantization"],
        "calibration": {
            "values": values,
            "uncertainties": {k: 1e-4 * v for k, v in values.items()},
            "reduced_chi2": 1.0,
            "noise": {"omega1": 0.001},
            "step": SolverSettings().max_step,
        },
    }


def test_the_model_at_the_truth_has_no_sample_in_another_cell_and_a_slightly_wrong_one_has_a_few() -> None:
    qf = load()
    record = simulate(PLANT, effects={"load_inertia": 1.3, "speed_quantization": Q}).test_window()[0]
    exact = qf.flips(record, model(1.3), None)
    assert exact["off_cell"] == 0 and exact["chi2n_omega1"] == pytest.approx(0.0, abs=1e-12)
    off = qf.flips(record, model(1.3 * 1.001), None)  # 0.1 % off: some level changes move by a sample
    assert 0 < off["off_cell"] < 100 and len(off["edge_q"]) == off["off_cell"]
    assert min(off["edge_q"]) < 0.05  # near an edge
    assert off["chi2n_omega1"] > 100.0 and off["chi2n_omega1_in_cell"] < 1e-6  # the flips are all the misfit


def test_a_step_wider_than_the_range_stops_at_the_bound() -> None:
    qf = load()
    assert qf.moved(1.0, 12.0, (0.0, 3.0)) == 3.0
    assert qf.moved(2.9, 12.0, (0.0, 3.0)) == 0.0  # towards the inside: the lower bound
    assert qf.moved(1.0, 0.1, (0.0, 3.0)) == pytest.approx(1.1)


def test_a_result_without_a_quantum_model_gives_none() -> None:
    qf = load()
    result = {"candidates": [{"effect": "load_inertia", "calibration": {"values": {}}}]}
    assert qf.quantum_model(result) is None


def test_a_stored_value_outside_the_search_box_is_refused_not_clipped() -> None:
    qf = load()
    record = simulate(PLANT, effects={"load_inertia": 1.3, "speed_quantization": Q}).test_window()[0]
    m = model(1.3)
    m["calibration"]["values"]["load_inertia"] = 9.0  # beyond the effect's range
    with pytest.raises(ValueError, match="load_inertia"):
        qf.flips(record, m, None)
