"""Model 1.8: a torque across the clutch as an unknown input (docs/model-changes.md).

The kernel agrees with the scipy reference for it as for every input (the table of
``tests/test_simulation_model_versions.py`` iterates ``DISTURBANCE_LOCI``). Here: it is a torque
from J1 to J2, so while the clutch is open the motor's side moves exactly as under the opposite
torque on J1 alone, and the wheel's side, which a torque on J1 alone leaves alone, moves too; and
a zero schedule is neutral.
"""

from __future__ import annotations

import numpy as np
import pytest

from engine.constants import CHANNELS
from engine.records import SampleGrid
from engine.simulation import DISTURBANCE_LOCI, Case, Disturbance, PlantParameters, simulate_batch
from engine.simulation.parameters import DISTURBANCE_MEANING, input_part
from engine.simulation.reference import ReferenceModel, _resolve, reference_inputs

NOMINAL = PlantParameters(K=0.005, J1=0.87, c=1.0)
#: From switch-on.
GRID = SampleGrid(sample_interval=2.5e-5, n_samples=12000, event_index=1400)


def _with(locus: str, value: float) -> Case:
    return Case(NOMINAL.replace(disturbance=Disturbance(locus, 0.0, 2.5e-3, (value,) * 120)))


def test_the_clutch_torque_is_an_input_of_the_clutch() -> None:
    assert "clutch_torque" in DISTURBANCE_LOCI and input_part("clutch_torque") == "clutch"
    assert input_part("load") == "load" and DISTURBANCE_MEANING["clutch_torque"][1] == "pu"


@pytest.mark.parametrize("gap", [0.0, 0.9, 1.2])  # the clutch open (inside the zone), and in contact
def test_it_is_minus_d_on_the_motor_shaft_and_plus_d_on_the_wheel(gap: float) -> None:
    """The reference's right-hand side: the input moves dw_1 by -d / T_1 and dw_2 by +d / T_2, nothing else,
    at a state inside the zone and at one in contact (where the contact's force is the same with and without it)."""
    d = 0.03
    schedule = {"locus": "clutch_torque", "t0": 0.0, "dt": 0.1, "values": [d, d, d]}
    values = _resolve(*reference_inputs(Case(NOMINAL)))
    plain, pushed = ReferenceModel(values), ReferenceModel(values, schedule)
    b = NOMINAL.K / NOMINAL.r  # the zone's half-width [rad]
    y = np.array([0.3, 0.2, -0.1, 0.05, 0.4, 0.35, 0.3, gap * b, 0.0, 0.0])
    dy0, ch0 = plain.derivatives(0.1, y, True)
    dy1, ch1 = pushed.derivatives(0.1, y, True)
    change = dy1 - dy0
    np.testing.assert_allclose(change[4:6], [-d / NOMINAL.T1, d / NOMINAL.T2], rtol=1e-12)
    assert np.all(change[:4] == 0.0) and np.all(change[6:] == 0.0)
    assert ch1[CHANNELS.index("m_el")] == ch0[CHANNELS.index("m_el")]


def test_a_zero_clutch_torque_is_neutral() -> None:
    res = simulate_batch([Case(NOMINAL), _with("clutch_torque", 0.0)])
    rel = np.max(np.abs(res.channels[1] - res.channels[0]), axis=1) / np.ptp(res.channels[0], axis=1)
    assert np.all(rel < 2e-4)
