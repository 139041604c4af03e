"""What a calibration searches: the free parameters, their search box, and the cases they define.

The plant parameters that are uncertain in practice are the backlash width K,
the motor-side inertia J1, the absorber viscosity c and the absorber
discontinuity c1 (:data:`CALIBRATED`); a record's conditions may fix any of
them. Their plausible operating range is defined once, in
:data:`engine.constants.OPERATING_RANGE` (the range the held-out evaluation, the
blind validation and the benchmarks draw from); the calibration's search box (:data:`DEFAULT_BOUNDS`) is that range widened by a
margin per parameter (:data:`SEARCH_MARGIN`), so that optima near an edge of
the operating range stay interior to the box.

A :class:`ModelSpace` maps points of the unit box ``[0, 1]^d`` to simulation
cases: every free parameter (:class:`FreeParameter`) on a linear or
logarithmic scale, optionally plus the scalar value of one unmodelled effect.

When a record's event was located from the data rather than given
(:class:`engine.records.EventLocation`), the event lies somewhere within one
sample interval before the located sample; the exact instant is then a free
nuisance parameter, :data:`ALIGNMENT` (the sensor chain's ``trigger_offset``
[s], searched over the located interval), so that the record is compared with
simulations sampled at its own instants however coarse its interval.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from engine.constants import OPERATING_RANGE
from engine.records import Record
from engine.simulation import Case, Effect, PlantParameters, SensorParameters

__all__ = [
    "ALIGNMENT",
    "CALIBRATED",
    "DEFAULT_BOUNDS",
    "LOG_SCALED_EFFECTS",
    "SEARCH_MARGIN",
    "FreeParameter",
    "ModelSpace",
    "default_space",
]

#: Margin of the search box beyond the operating range, ``name -> (below, above)``, in the
#: parameter's unit: K 0.3 mm below and 0.5 mm above, J1 0.03 kg m^2 either side, c 0.05 pu
#: below and 0.1 pu above.
SEARCH_MARGIN: dict[str, tuple[float, float]] = {
    "K": (0.0003, 0.0005),
    "J1": (0.03, 0.03),
    "c": (0.05, 0.1),
}
#: Search interval of c1 [pu]: it has no operating range (records usually give it).
C1_BOUNDS: tuple[float, float, str] = (0.0, 0.6, "pu")


def _widened(name: str) -> tuple[float, float, str]:
    """The operating range of ``name`` widened by its search margin.

    The edges are rounded to 1e-12 of the unit, which removes the binary
    representation error of the decimal sums (0.93 + 0.03 gives 0.96, not
    0.9600000000000001).
    """
    lo, hi, unit = OPERATING_RANGE[name]
    below, above = SEARCH_MARGIN[name]
    return round(lo - below, 12), round(hi + above, 12), unit


#: Default search box of the calibrated plant parameters: ``name -> (low, high, unit)``
#: (K 0.0022-0.0105 m, J1 0.72-0.96 kg m^2, c 0.75-1.6 pu, c1 0-0.6 pu).
DEFAULT_BOUNDS: dict[str, tuple[float, float, str]] = {
    **{name: _widened(name) for name in OPERATING_RANGE},
    "c1": C1_BOUNDS,
}
#: Plant parameters a record's conditions may fix (MODEL.md; others are nominal).
CALIBRATED: tuple[str, ...] = ("K", "J1", "c", "c1")
#: The free parameter that places a located event within its sample interval: the sensor
#: chain's ``trigger_offset`` [s] (the true event lies that long after the located sample).
ALIGNMENT: str = "trigger_offset"
#: Effects that are pure time shifts of every channel: absorbed by :data:`ALIGNMENT` when it is free.
TIME_SHIFT_EFFECTS: frozenset[str] = frozenset({"trigger_offset", "measurement_delay"})
#: Effects whose value is best searched on a logarithmic scale.
LOG_SCALED_EFFECTS: frozenset[str] = frozenset({"contact_stiffness", "contact_damping", "sensor_lowpass"})


@dataclass(frozen=True)
class FreeParameter:
    """One fitted parameter and its search interval.

    Parameters
    ----------
    name : str
        Plant field (``K``, ``J1``, ``c``, ``c1``) or effect name.
    lo, hi : float
        Search interval, in the parameter's unit.
    unit : str
        Unit of the value.
    log : bool
        Search on a logarithmic scale (needs ``lo > 0``).
    """

    name: str
    lo: float
    hi: float
    unit: str = ""
    log: bool = False

    def value(self, u: np.ndarray | float) -> np.ndarray | float:
        """Map unit-box coordinate(s) u in [0, 1] to value(s), in the parameter's unit."""
        u = np.clip(u, 0.0, 1.0)
        if self.log:
            return self.lo * (self.hi / self.lo) ** u
        return self.lo + (self.hi - self.lo) * u

    def unit_coord(self, v: float) -> float:
        """Inverse of :meth:`value`: the unit-box coordinate of value ``v`` (clipped to the interval)."""
        v = min(max(float(v), self.lo), self.hi)
        if self.log:
            return math.log(v / self.lo) / math.log(self.hi / self.lo)
        return (v - self.lo) / (self.hi - self.lo)

    def dvalue_du(self, u: float) -> float:
        """Derivative of :meth:`value` with respect to u, in the parameter's unit (for uncertainties)."""
        if self.log:
            return float(self.value(u)) * math.log(self.hi / self.lo)
        return self.hi - self.lo


@dataclass(frozen=True)
class ModelSpace:
    """The family of cases a calibration searches.

    Parameters
    ----------
    base : Case
        The plant with every known condition applied (fixed parameters).
    params : tuple of FreeParameter
        Free plant parameters, then (optionally) the effect's value last.
    effect : Effect or None
        The unmodelled effect whose value is the last free parameter.
    """

    base: Case
    params: tuple[FreeParameter, ...]
    effect: Effect | None = None

    @property
    def dim(self) -> int:
        """Number of free parameters."""
        return len(self.params)

    @property
    def aligned(self) -> bool:
        """Whether the event instant is a free parameter (:data:`ALIGNMENT`; the record's event was located)."""
        return ALIGNMENT in self.names

    @property
    def names(self) -> list[str]:
        """Names of the free parameters, in order."""
        return [p.name for p in self.params]

    def values(self, u: np.ndarray) -> dict[str, float]:
        """Parameter values at unit-box point u (each in its unit)."""
        return {p.name: float(p.value(ui)) for p, ui in zip(self.params, u, strict=True)}

    def unit(self, values: Mapping[str, float]) -> np.ndarray:
        """Unit-box point of parameter values (missing names at the box centre)."""
        return np.array([p.unit_coord(values[p.name]) if p.name in values else 0.5 for p in self.params])

    def case(self, u: np.ndarray) -> Case:
        """The simulation case at unit-box point u."""
        vals = self.values(u)
        own = {k: v for k, v in vals.items() if self.effect is None or k != self.effect.name}
        sensor_changes = {k: v for k, v in own.items() if k in _SENSOR_FIELDS}
        plant_changes = {k: v for k, v in own.items() if k not in _SENSOR_FIELDS}
        case = Case(self.base.plant.replace(**plant_changes), self.base.sensors.replace(**sensor_changes))
        if self.effect is not None:
            case = self.effect.apply(case, vals[self.effect.name])
        return case

    def with_effect(self, effect: Effect) -> ModelSpace:
        """This space plus one effect's value as an extra free parameter (searched over the effect's bounds)."""
        lo, hi = effect.bounds
        log = effect.name in LOG_SCALED_EFFECTS and lo > 0
        return ModelSpace(self.base, (*self.params, FreeParameter(effect.name, lo, hi, effect.unit, log)), effect)


def default_space(record: Record, bounds: Mapping[str, tuple[float, float, str]] | None = None) -> ModelSpace:
    """Parameter space of a record: K, J1, c, c1 are free unless its conditions fix them.

    Parameters
    ----------
    record : Record
        Its ``conditions`` may fix ``K`` [m], ``J1`` [kg m^2], ``c`` [pu], ``c1`` [pu]
        (and any other ``PlantParameters`` field, which is then applied as known).
        When its event was located from the data, the event instant within the
        located interval is free too (:data:`ALIGNMENT`, last).
    bounds : mapping, optional
        Search box per free parameter, ``name -> (low, high, unit)``;
        defaults to :data:`DEFAULT_BOUNDS`.

    Returns
    -------
    ModelSpace
        Without an effect.
    """
    bounds = dict(DEFAULT_BOUNDS if bounds is None else bounds)
    plant_fields = set(PlantParameters.__dataclass_fields__)
    known = {k: v for k, v in record.conditions.items() if k in plant_fields}
    base = Case(PlantParameters(**known))
    free = tuple(
        FreeParameter(name, bounds[name][0], bounds[name][1], bounds[name][2])
        for name in CALIBRATED
        if name not in known
    )
    if record.event_location is not None:
        lo, hi = record.event_location.interval
        free = (*free, FreeParameter(ALIGNMENT, lo, hi, "s"))
    return ModelSpace(base, free)


_SENSOR_FIELDS = frozenset(SensorParameters.__dataclass_fields__)
