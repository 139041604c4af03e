"""The calibrated case changed for a probe or a trial.

With an unknown input d(t) at a locus, with more Coulomb friction against a part's motion [pu],
or with its calibrated parameters moved: each by a small step (for their response columns) or by
a fitted move (in the parameters' units).
"""

from __future__ import annotations

import numpy as np

from engine.simulation import Case, Disturbance
from engine.simulation.parameters import COULOMB_FIELDS

#: Steps of the calibrated parameters' response columns, in their units (relative for K, J1, c).
_PARAM_STEP_REL: dict[str, float] = {"K": 1e-3, "J1": 1e-3, "c": 1e-3}
_PARAM_STEP_ABS: dict[str, float] = {"c1": 1e-3, "trigger_offset": 1e-6}


def with_input(case: Case, dist: Disturbance) -> Case:
    return Case(case.plant.replace(disturbance=dist), case.sensors)


def with_friction(case: Case, locus: str, f: float) -> Case:
    """``case`` with ``f`` [pu] more Coulomb friction against the motion of the part at ``locus``."""
    if f == 0.0:
        return case
    name = COULOMB_FIELDS[locus]
    return Case(case.plant.replace(**{name: getattr(case.plant, name) + f}), case.sensors)


def parameter_cases(case: Case, names: list[str]) -> tuple[list[Case], list[float], list[str]]:
    """The calibrated parameters, each moved by a small step (for their response columns)."""
    out, steps, used = [], [], []
    for name in names:
        if name in _PARAM_STEP_REL:
            h = _PARAM_STEP_REL[name] * float(getattr(case.plant, name))
            out.append(Case(case.plant.replace(**{name: getattr(case.plant, name) + h}), case.sensors))
        elif name == "c1":
            h = _PARAM_STEP_ABS[name]
            out.append(Case(case.plant.replace(c1=case.plant.c1 + h), case.sensors))
        elif name == "trigger_offset":
            h = _PARAM_STEP_ABS[name]
            lo = -0.005 + h
            t0 = min(max(case.sensors.trigger_offset, lo), 0.005 - h)
            out.append(Case(case.plant, case.sensors.replace(trigger_offset=t0 + h)))
        else:
            continue  # an effect's value fitted with the calibration: not projected
        steps.append(h)
        used.append(name)
    return out, steps, used


def with_moves(case: Case, names: list[str], p: np.ndarray) -> Case:
    """``case`` with its calibrated parameters moved by ``p`` (kept when that is not a valid case)."""
    moved = {k: current(case, k) + float(v) for k, v in zip(names, p, strict=True)}
    plant = {k: v for k, v in moved.items() if hasattr(case.plant, k)}
    sensors = {k: v for k, v in moved.items() if k not in plant}
    try:
        return Case(case.plant.replace(**plant), case.sensors.replace(**sensors)).validate()
    except ValueError:
        return case


def current(case: Case, name: str) -> float:
    """A calibrated parameter's value in a case (plant or sensors)."""
    return float(getattr(case.plant, name) if hasattr(case.plant, name) else getattr(case.sensors, name))
