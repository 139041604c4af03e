"""Shared helpers of the model-version tests that check one kernel term at a state against its definition
(``tests/test_simulation_model_1_4.py`` to ``tests/test_simulation_model_1_8.py``)."""

from __future__ import annotations

import math

import numpy as np

from engine.simulation import Case, EffectLibrary, PlantParameters
from engine.simulation import _kernel as kern
from engine.simulation.simulator import parameter_vector

#: The nominal plant of those tests.
NOMINAL = PlantParameters(K=0.005, J1=0.87, c=1.0)
#: A state of the tests' order of magnitude (fluxes, speeds, angles; no sensor states), the
#: clutch's deflection theta_1 - theta_2 = 0.03 rad inside the nominal zone (b = 0.05 rad).
STATE = (0.9, -0.3, 0.8, -0.35, 0.02, 0.012, 0.004, 0.07, 0.04, 0.01, 0.0, 0.0, 0.0, 0.0, 0.0)
#: Index of each named state in ``STATE``.
STATE_INDEX = {"w1": 4, "w2": 5, "w3": 6, "th1": 7, "th2": 8, "th3": 9}


def vectors(family: EffectLibrary, name: str, value: float, case: Case | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The parameter vectors of ``case`` (the nominal plant) without and with one effect of ``family``, both on
    the extended path (so that their difference is the term alone), never switched off."""
    base = Case(NOMINAL) if case is None else case
    P0 = parameter_vector(base)
    P1 = parameter_vector(family[name].apply(base, value))
    P0[kern.P_EXTENDED] = 1.0
    P0[kern.P_T_SWITCH_OFF] = P1[kern.P_T_SWITCH_OFF] = math.inf
    return P0, P1


def rhs(
    P: np.ndarray, y: tuple[float, ...] = STATE, t: float = 0.01, motor_on: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """The kernel's right-hand side and channels at ``(t, y)``."""
    dy, ch = kern.rhs(t, y, P, motor_on)
    return np.array(dy), np.array(ch)


def with_state(y: tuple[float, ...], **at: float) -> tuple[float, ...]:
    """``y`` with some of its entries replaced, by name (``w1`` .. ``w3``, ``th1`` .. ``th3``)."""
    out = list(y)
    for key, value in at.items():
        out[STATE_INDEX[key]] = value
    return tuple(out)
