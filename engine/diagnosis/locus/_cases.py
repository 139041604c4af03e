"""The calibrated case changed for a probe or a trial.

With an unknown input d(t) at a locus, with a term of a part's own (more Coulomb friction against
its motion [pu], or one of its MODEL.md parameters drifted by a factor), or with its calibrated
parameters moved: each by a small step (for their response columns) or by a fitted move (in the
parameters' units).
"""

from __future__ import annotations

import numpy as np

from engine.simulation import Case, Disturbance
from engine.simulation.parameters import COULOMB_FIELDS, PART_FIELDS

#: Steps of the calibrated parameters' response columns, in their units (relative for K, J1, c).
_PARAM_STEP_REL: dict[str, float] = {"K": 1e-3, "J1": 1e-3, "c": 1e-3}
_PARAM_STEP_ABS: dict[str, float] = {"c1": 1e-3, "trigger_offset": 1e-6}


def with_input(case: Case, dist: Disturbance) -> Case:
    return Case(case.plant.replace(disturbance=dist), case.sensors)


#: Smallest factor of a drifted part parameter (a factor must stay positive).
MIN_DRIFT: float = -0.9


def is_coulomb(field: str) -> bool:
    """Whether a part term's field is a Coulomb friction (added [pu]) rather than a drifted parameter."""
    return field in COULOMB_FIELDS.values()


def part_terms(locus: str, calibrated: list[str]) -> list[str]:
    """The fields of the part terms of ``locus`` the estimate tries: those the calibration does not fit."""
    fields = ([COULOMB_FIELDS[locus]] if locus in COULOMB_FIELDS else []) + list(PART_FIELDS.get(locus, {}))
    return [f for f in fields if f not in calibrated]


def with_term(case: Case, field: str, value: float) -> Case:
    """``case`` with a term of a part's own: ``value`` [pu] more Coulomb friction when ``field`` is one
    of :data:`COULOMB_FIELDS`, else the parameter ``field`` times ``1 + value`` (at least ``1 +
    MIN_DRIFT``)."""
    if value == 0.0 or not field:
        return case
    if is_coulomb(field):
        return Case(case.plant.replace(**{field: getattr(case.plant, field) + value}), case.sensors)
    new = float(getattr(case.plant, field)) * (1.0 + max(value, MIN_DRIFT))
    return Case(case.plant.replace(**{field: new}), case.sensors)


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
