"""Held-out prediction: parameters fitted on some records of a plant, the force (every channel) of others predicted.

The honest test of a named effect is whether it helps where it was not fitted. :func:`held_out`
fits the plant's calibrated parameters, shared across the training records, once alone (the
nominal model) and once with the given effects (their scalars shared as well), by bounded least
squares on the stacked channel-normalised residuals (:class:`~engine.diagnosis.plant_gap.PlantObjective`),
then simulates every test record with both parameter sets and reports the relative error per
channel (the authors' eq. 11 of the EMPS report, ``100 ||y - y_model|| / ||y||``), beside the test
record's own calibration (the nominal model fitted on the test record itself: what no prediction
can beat without new physics).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from engine.diagnosis.plant_gap import N_SCAN, PlantObjective, calibrate, solve_unit_box
from engine.plants.base import CalibratedParameter, Plant, free_parameters

__all__ = ["HeldOut", "fit_shared", "held_out"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class HeldOut:
    """Errors of a prediction on held-out records.

    Attributes
    ----------
    train, test : list of str
        The records fitted and the records predicted.
    effects : list of str
        The effects carried over.
    nominal, with_effects : dict of str to float
        The parameters fitted on the training records without and with the effects.
    relative_error : dict
        ``{test record: {"nominal": {channel: %}, "with_effects": {...}, "own_calibration": {...}}}``.
    train_error : dict
        The same on the training records (in-sample).
    """

    train: list[str]
    test: list[str]
    effects: list[str]
    nominal: dict[str, float]
    with_effects: dict[str, float]
    relative_error: dict[str, dict[str, dict[str, float]]]
    train_error: dict[str, dict[str, dict[str, float]]]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "train": self.train,
            "test": self.test,
            "effects": self.effects,
            "parameters": {"nominal": self.nominal, "with_effects": self.with_effects},
            "relative_error": self.relative_error,
            "train_error": self.train_error,
        }


def fit_shared(
    plant: Plant, objectives: Sequence[PlantObjective], free: Sequence[CalibratedParameter], start: Mapping[str, float]
) -> tuple[dict[str, float], float]:
    """Bounded least squares of ``free``, shared by every record, on their stacked residuals.

    Returns the fitted values and the cost. Raises ``RuntimeError`` when the solver fails.
    """

    def values(z: np.ndarray) -> dict[str, float]:
        return {p.name: float(p.value(zi - 1.0)) for p, zi in zip(free, z, strict=True)}

    def vector(z: np.ndarray) -> np.ndarray:
        v = values(z)
        return np.concatenate([o.vector(v) for o in objectives])

    u0 = np.array([p.unit_coord(start.get(p.name, p.nominal)) for p in free])
    res = solve_unit_box(vector, u0, plant.diff_step, [p.name for p in free])
    return values(res.x), float(res.fun @ res.fun)


def _scan_start(
    objectives: Sequence[PlantObjective], base: Mapping[str, float], effects: Sequence[CalibratedParameter]
) -> dict[str, float]:
    """Each effect's best value on a scan of its range, the others held (a start for the joint fit)."""
    start = dict(base)
    for e in effects:
        best_v, best_c = e.nominal, math.inf
        for u in np.linspace(0.0, 1.0, N_SCAN):
            v = float(e.value(float(u)))
            c = sum(float(r @ r) for r in (o.vector({**start, e.name: v}) for o in objectives))
            if c < best_c:
                best_v, best_c = v, c
        start[e.name] = best_v
    return start


def held_out(plant: Plant, train: Sequence[Any], test: Sequence[Any], effects: Sequence[str]) -> HeldOut:
    """Fit on ``train`` without and with ``effects``; predict ``test`` (module docstring).

    Raises
    ------
    KeyError
        For an effect not in the plant's catalogue.
    ValueError
        For no training or no test records, or records that fix different calibrated parameters.
    """
    if not train or not test:
        raise ValueError("give at least one training and one test record")
    for name in effects:
        if name not in plant.catalogue:
            raise KeyError(f"plant {plant.name!r} has no effect {name!r}; known: {', '.join(plant.catalogue)}")
    free = free_parameters(plant, train[0])
    if any({p.name for p in free_parameters(plant, r)} != {p.name for p in free} for r in (*train, *test)):
        raise ValueError("the records fix different calibrated parameters; a shared calibration needs the same ones")
    objs = [PlantObjective(plant, r) for r in train]
    start = {
        p.name: float(np.median([calibrate(plant, o.record, objective=o).values[p.name] for o in objs])) for p in free
    }
    nominal, _ = fit_shared(plant, objs, free, start)
    eff = [plant.catalogue[n].as_parameter() for n in effects]
    start_eff = _scan_start(objs, nominal, eff)
    with_effects, _ = fit_shared(plant, objs, [*free, *eff], start_eff)

    def errors(records: Sequence[Any], own: bool) -> dict[str, dict[str, dict[str, float]]]:
        out = {}
        for r in records:
            o = PlantObjective(plant, r)
            row = {"nominal": o.relative_errors(nominal), "with_effects": o.relative_errors(with_effects)}
            if own:
                row["own_calibration"] = o.relative_errors(calibrate(plant, r, objective=o).values)
            out[getattr(r, "name", "")] = row
        return out

    result = HeldOut(
        train=[getattr(r, "name", "") for r in train],
        test=[getattr(r, "name", "") for r in test],
        effects=list(effects),
        nominal=nominal,
        with_effects=with_effects,
        relative_error=errors(test, own=True),
        train_error=errors(train, own=False),
    )
    logger.info("held-out prediction of %s from %s: %s", result.test, result.train, result.relative_error)
    return result
