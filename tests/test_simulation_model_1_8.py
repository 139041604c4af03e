"""Model 1.8: a torque across the clutch as an unknown input (docs/model-changes.md).

The kernel agrees with the scipy reference for it as for every input (the table of
``tests/test_simulation_model_versions.py`` iterates ``DISTURBANCE_LOCI``). Here: it is a torque
from J1 to J2 (the kernel's right-hand side moves dw_1 by -d / T_1 and dw_2 by +d / T_2 and nothing
else, inside the zone and in contact), and a zero schedule is neutral.
"""

from __future__ import annotations

import numpy as np
import pytest
from kernel_terms import NOMINAL, STATE, rhs, with_state

from engine.constants import CHANNELS
from engine.simulation import DISTURBANCE_LOCI, Case, Disturbance, simulate_batch
from engine.simulation.parameters import DISTURBANCE_MEANING, input_part
from engine.simulation.simulator import parameter_vector


def _with(locus: str, value: float) -> Case:
    return Case(NOMINAL.replace(disturbance=Disturbance(locus, 0.0, 2.5e-3, (value,) * 120)))


def test_the_clutch_torque_is_an_input_of_the_clutch() -> None:
    assert "clutch_torque" in DISTURBANCE_LOCI and input_part("clutch_torque") == "clutch"
    assert input_part("load") == "load" and DISTURBANCE_MEANING["clutch_torque"][1] == "pu"


@pytest.mark.parametrize("gap", [0.0, 0.9, 1.2])  # the clutch open (inside the zone), and in contact
def test_it_is_minus_d_on_the_motor_shaft_and_plus_d_on_the_wheel(gap: float) -> None:
    """The kernel's right-hand side: the input moves dw_1 by -d / T_1 and dw_2 by +d / T_2, nothing else,
    at a state inside the zone and at one in contact (where the contact's force is the same with and without it);
    the reference agrees with the kernel on whole records (the versions table)."""
    d = 0.03
    P0 = parameter_vector(Case(NOMINAL.replace(disturbance=Disturbance("clutch_torque", 0.0, 0.1, (0.0,) * 3))))
    P1 = parameter_vector(Case(NOMINAL.replace(disturbance=Disturbance("clutch_torque", 0.0, 0.1, (d,) * 3))))
    b = NOMINAL.K / NOMINAL.r  # the zone's half-width [rad]
    y = with_state(STATE, th1=gap * b, th2=0.0)
    dy0, ch0 = rhs(P0, y, t=0.1)
    dy1, ch1 = rhs(P1, y, t=0.1)
    change = dy1 - dy0
    np.testing.assert_allclose(change[4:6], [-d / NOMINAL.T1, d / NOMINAL.T2], rtol=1e-12)
    assert np.all(change[:4] == 0.0) and np.all(change[6:] == 0.0)
    assert ch1[CHANNELS.index("m_el")] == ch0[CHANNELS.index("m_el")]


def test_a_zero_clutch_torque_is_neutral() -> None:
    res = simulate_batch([Case(NOMINAL), _with("clutch_torque", 0.0)])
    rel = np.max(np.abs(res.channels[1] - res.channels[0]), axis=1) / np.ptp(res.channels[0], axis=1)
    assert np.all(rel < 2e-4)
