"""MODEL.md section 4: the kernel agrees with a tight-tolerance scipy solution.

The reference (engine.simulation.reference) is an independent transcription of
MODEL.md in complex notation, integrated by solve_ivp (DOP853, rtol 1e-9,
atol 1e-12) with the event located by solve_ivp's event function.
"""

import numpy as np
import pytest

from engine.constants import CHANNELS
from engine.simulation import Case, PlantParameters, apply_effects, simulate_batch
from engine.simulation.reference import reference_simulate

CASES = [
    # grid cases (paper's J1 and widths, c groups)
    dict(K=0.0025, J1=0.8482, c=0.8),
    dict(K=0.0075, J1=0.8917, c=1.25),
    dict(K=0.01, J1=0.7612, c=1.4),
    # off-grid cases
    dict(K=0.0063, J1=0.78, c=1.37),
    dict(K=0.0031, J1=0.925, c=1.5),
]

EFFECT_CASES = [
    (dict(K=0.005, J1=0.87, c=1.0), {"contact_stiffness": 10.0}),
    (dict(K=0.004, J1=0.76, c=0.9), {"motor_coulomb_friction": 0.1, "rotor_resistance_drift": 1.6}),
    (dict(K=0.009, J1=0.92, c=1.5), {"measurement_delay": 0.001}),
    (dict(K=0.0025, J1=0.93, c=1.5), {"contact_damping": 0.1, "supply_voltage": 0.8}),
]


def _compare(case: Case) -> tuple[np.ndarray, float]:
    ref = reference_simulate(case)
    sim = simulate_batch([case])
    pp = np.ptp(ref.channels, axis=1)
    rel = np.max(np.abs(sim.channels[0] - ref.channels), axis=1) / pp
    return rel, abs(sim.event_times[0] - ref.event_time)


@pytest.mark.parametrize("kw", CASES, ids=lambda kw: f"K{kw['K']}-J{kw['J1']}-c{kw['c']}")
def test_reference_plant_matches_tight_solution(kw):
    rel, dte = _compare(Case(PlantParameters(**kw)))
    assert dte < 1e-6, f"t_e differs by {dte:.3e} s"
    for name, e in zip(CHANNELS, rel):
        assert e < 0.005, f"{name}: max error {100 * e:.3f} % of peak-to-peak"


@pytest.mark.parametrize("kw,effects", EFFECT_CASES, ids=lambda v: str(v))
def test_effect_cases_match_tight_solution(kw, effects):
    rel, dte = _compare(apply_effects(Case(PlantParameters(**kw)), effects))
    assert dte < 1e-6
    assert np.all(rel < 0.005), dict(zip(CHANNELS, np.round(100 * rel, 4)))
