"""What a calibration searches: the free parameters, their search box, and the cases they define.

The plant parameters that are uncertain in practice are the backlash width K,
the motor-side inertia J1, the absorber viscosity c and the absorber
discontinuity c1 (:data:`CALIBRATED`); a record's conditions may fix any of
them. The calibration's default search box (:data:`DEFAULT_BOUNDS`) is the
plausible box of :data:`engine.constants.PLAUSIBLE_RANGE` (K 1-15 mm, J1
0.6-1.2 kg m^2, c 0.5-2.0 pu) plus c1 in [0, 0.6] pu, far wider than the
operating range the v1 validation draws from
(:data:`engine.constants.OPERATING_RANGE`). A caller may pass its own box
(:func:`default_space`'s ``bounds``, checked by :func:`check_bounds`), e.g. a
narrower one when the drive is better known. K is searched on a logarithmic
scale (:data:`LOG_SCALED_PARAMETERS`): its cost basin is a fixed fraction of K
wide (about +-3 %), so on a log scale it has the same width in the unit box
wherever K lies.

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
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from engine.constants import C1_NOMINAL, C_NOMINAL, J1_NOMINAL, K_NOMINAL, PLAUSIBLE_RANGE
from engine.plants.base import FreeParameter
from engine.records import Record
from engine.simulation import (
    Case,
    Effect,
    EffectLibrary,
    ParameterError,
    PlantParameters,
    SensorParameters,
    SolverSettings,
)
from engine.simulation.drive import REFERENCE_DRIVE, DriveDescription

__all__ = [
    "ALIGNMENT",
    "CALIBRATED",
    "DEFAULT_BOUNDS",
    "LOG_SCALED_EFFECTS",
    "LOG_SCALED_PARAMETERS",
    "Bounds",
    "BoundsError",
    "FreeParameter",
    "ModelSpace",
    "across_switch_off",
    "check_bounds",
    "default_space",
    "drive_bounds",
    "indistinguishable",
    "nominal_ratios",
    "scan_grid",
]

#: Search interval of c1 [pu]: it has no operating range (records usually give it).
C1_BOUNDS: tuple[float, float, str] = (0.0, 0.6, "pu")
#: Default search box of the calibrated plant parameters: ``name -> (low, high, unit)``
#: (K 0.001-0.015 m, J1 0.6-1.2 kg m^2, c 0.5-2.0 pu: :data:`engine.constants.PLAUSIBLE_RANGE`;
#: c1 0-0.6 pu).
DEFAULT_BOUNDS: dict[str, tuple[float, float, str]] = {**PLAUSIBLE_RANGE, "c1": C1_BOUNDS}
#: The nominal value each of :data:`DEFAULT_BOUNDS` is relative to, for a described drive (:func:`drive_bounds`):
#: parameter -> MODEL.md's nominal value (c1's box follows c when a drive has no absorber discontinuity).
BOX_NOMINALS: dict[str, float] = {"K": K_NOMINAL, "J1": J1_NOMINAL, "c": C_NOMINAL, "c1": C1_NOMINAL}
#: Calibrated plant parameters searched on a logarithmic scale.
LOG_SCALED_PARAMETERS: frozenset[str] = frozenset({"K"})
#: Plant parameters a record's conditions may fix (MODEL.md; others are nominal).
CALIBRATED: tuple[str, ...] = ("K", "J1", "c", "c1")
#: The free parameter that places a located event within its sample interval: the sensor
#: chain's ``trigger_offset`` [s] (the true event lies that long after the located sample).
ALIGNMENT: str = "trigger_offset"
#: Effects that are pure time shifts of every channel: absorbed by :data:`ALIGNMENT` when it is free.
TIME_SHIFT_EFFECTS: frozenset[str] = frozenset({"trigger_offset", "measurement_delay"})

#: Where a scan of a time shift (:data:`TIME_SHIFT_EFFECTS`) samples each sample interval of the
#: record, as fractions of it: twice per interval (the chi-square of a shift has a basin per period
#: of the record's fastest content, often narrower than the 0.5 ms between the values of a 9-value
#: scan of +-2 ms), and never on a multiple of the interval, where a sample crosses the switch-off
#: instant and the model's currents and torque jump to zero (docs/diagnosis.md 8b, *Scans of a
#: time shift*).
SHIFT_SCAN_OFFSETS: tuple[float, ...] = (0.25, 0.75)
#: Most values of one scan of a time shift (a record on a very fine grid).
MAX_SHIFT_SCAN: int = 201
#: A fitted time shift this close to a multiple of the sample interval (fraction of the interval) may
#: have stopped at the edge of a jump of the chi-square; the fit is tried again from the other side.
SHIFT_EDGE: float = 0.05

#: Effects whose value is best searched on a logarithmic scale.
LOG_SCALED_EFFECTS: frozenset[str] = frozenset({"contact_stiffness", "contact_damping", "sensor_lowpass"})


def indistinguishable(name: str, value: float, library: EffectLibrary) -> tuple[str, ...]:
    """Other effects of ``library`` that give the very same record as effect ``name`` at ``value``.

    Two pure time shifts of every channel (:data:`TIME_SHIFT_EFFECTS`: a measurement delay and a
    trigger offset) simulate identical records wherever their ranges overlap (MODEL.md, sensor
    chain: the sample k holds the value at ``t_e + (k - E) Ts - (delay + trigger_offset)``); no
    record can tell them apart, so a diagnosis naming one must say that it may be the other.

    Parameters
    ----------
    name : str
        The named effect.
    value : float
        Its fitted value, in its unit.
    library : EffectLibrary
        The candidate effects.

    Returns
    -------
    tuple of str
        The other effects (empty when the named effect has no twin at this value).
    """
    if name not in TIME_SHIFT_EFFECTS or not math.isfinite(value):
        return ()
    return tuple(
        n
        for n in library
        if n != name and n in TIME_SHIFT_EFFECTS and library[n].bounds[0] <= value <= library[n].bounds[1]
    )


def _shift_axis(space: ModelSpace, i: int) -> bool:
    """Whether coordinate ``i`` of ``space`` is the value of a time-shift effect."""
    first = space.dim - len(space.effects)
    return i >= first and space.effects[i - first].name in TIME_SHIFT_EFFECTS


def _other_shift(space: ModelSpace, i: int, u: np.ndarray) -> float:
    """The rest of the case's total shift (delay + trigger offset) [s] beside the shift of coordinate ``i``
    at point ``u``: a shift effect sets its own field, the other field comes from the record's conditions
    or the alignment (:data:`ALIGNMENT`)."""
    sensors = space.case(u).sensors
    return float(sensors.delay + sensors.trigger_offset - space.params[i].value(u[i]))


def scan_grid(space: ModelSpace, i: int, u: np.ndarray, record: Record, n_scan: int) -> np.ndarray:
    """Unit-box coordinates of a one-dimensional scan of coordinate ``i`` of ``space`` at point ``u``.

    ``n_scan`` values evenly spaced over the range for most coordinates. For the value of a pure
    time shift (:data:`TIME_SHIFT_EFFECTS`) the scan must land in the basin of the true shift,
    which is often narrower than a coarse scan's spacing, and must avoid the shifts at which a
    sample crosses the model's switch-off instant (the case's total shift a multiple of the
    sample interval, the event lying on a sample), where the chi-square jumps:
    :data:`SHIFT_SCAN_OFFSETS` within every sample interval of the range (at most
    :data:`MAX_SHIFT_SCAN` values, thinned evenly). The total shift counts any delay or trigger
    offset the record's conditions or the alignment give beside the scanned effect.

    Parameters
    ----------
    space : ModelSpace
        The space scanned.
    i : int
        The scanned coordinate.
    u : ndarray, shape (space.dim,)
        The point the other coordinates keep.
    record : Record
        The record fitted (its sample interval [s]).
    n_scan : int
        Values of the scan of any other coordinate.

    Returns
    -------
    ndarray
        Unit-box coordinates of the scanned values, ascending.
    """
    if not _shift_axis(space, i):
        return np.linspace(0.0, 1.0, n_scan)
    param = space.params[i]
    ts = record.sample_interval
    rest = _other_shift(space, i, u)
    m = np.arange(math.floor((param.lo + rest) / ts), math.ceil((param.hi + rest) / ts))
    values = ((m[:, None] + np.asarray(SHIFT_SCAN_OFFSETS)[None]) * ts).ravel() - rest
    values = values[(values >= param.lo) & (values <= param.hi)]
    if values.size > MAX_SHIFT_SCAN:
        values = values[:: math.ceil(values.size / MAX_SHIFT_SCAN)]
    if values.size < 2:
        return np.linspace(0.0, 1.0, n_scan)
    return np.array([param.unit_coord(v) for v in values])


def across_switch_off(space: ModelSpace, u: np.ndarray, record: Record) -> list[np.ndarray]:
    """Points on the other side of the chi-square's jump from a fit whose time shift stopped at its edge.

    A least-squares fit of a time shift (:data:`TIME_SHIFT_EFFECTS`) cannot cross the shifts at which
    a sample crosses the switch-off instant (see :func:`scan_grid`): when the rest of the record
    pulls the shift towards the true value beyond such a jump, the fit stops at its edge. For every
    shift effect of ``space`` whose total shift lies within :data:`SHIFT_EDGE` sample intervals of a
    multiple of the interval, the point ``u`` with that shift moved a quarter interval to the other
    side of the jump.

    Parameters
    ----------
    space : ModelSpace
        The space fitted.
    u : ndarray, shape (space.dim,)
        The fit, in unit-box coordinates.
    record : Record
        The record fitted (its sample interval [s]).

    Returns
    -------
    list of ndarray
        The points to refit from (empty when no shift lies at an edge).
    """
    out: list[np.ndarray] = []
    ts = record.sample_interval
    for i in range(space.dim):
        if not _shift_axis(space, i):
            continue
        param = space.params[i]
        v = float(param.value(u[i]))
        total = v + _other_shift(space, i, u)
        m = round(total / ts)
        delta = total - m * ts
        if abs(delta) > SHIFT_EDGE * ts:
            continue
        other = v - delta - math.copysign(0.25, delta) * ts  # the jump, then a quarter interval across
        if param.lo <= other <= param.hi:
            w = np.array(u, dtype=float)
            w[i] = param.unit_coord(other)
            out.append(w)
    return out


@dataclass(frozen=True)
class ModelSpace:
    """The family of cases a calibration searches.

    Parameters
    ----------
    base : Case
        The plant with every known condition applied (fixed parameters).
    params : tuple of FreeParameter
        Free plant parameters, then (optionally) the effects' values last, in the order of ``effects``.
    effects : tuple of Effect
        The unmodelled effects whose values are the last free parameters (none for the nominal
        model, one for a candidate effect, up to three for a candidate set).
    drive : DriveDescription
        The drive whose plant ``base`` is (default MODEL.md's reference): its ``t_event_max`` [s] bounds every
        simulation of the space (:meth:`solver`), and the checks that compare a record with what the plant can
        produce read its envelopes (:mod:`engine.diagnosis.plausibility`).
    """

    base: Case
    params: tuple[FreeParameter, ...]
    effects: tuple[Effect, ...] = ()
    drive: DriveDescription = REFERENCE_DRIVE

    def solver(self, max_step: float) -> SolverSettings:
        """Integrator settings for the space's simulations: RK4 steps of at most ``max_step`` [s], the event
        within the drive's ``t_event_max`` [s]."""
        return self.drive.solver(max_step)

    @property
    def effect(self) -> Effect | None:
        """The last effect added (the only one of a single-effect space); None for the nominal model."""
        return self.effects[-1] if self.effects else None

    @property
    def effect_names(self) -> list[str]:
        """Names of the effects, in order."""
        return [e.name for e in self.effects]

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

    def case(self, u: np.ndarray, without: Collection[str] = ()) -> Case:
        """The simulation case at unit-box point u (the effects applied in order, but those named in ``without``)."""
        vals = self.values(u)
        mine = set(self.effect_names)
        own = {k: v for k, v in vals.items() if k not in mine}
        sensor_changes = {k: v for k, v in own.items() if k in _SENSOR_FIELDS}
        plant_changes = {k: v for k, v in own.items() if k not in _SENSOR_FIELDS}
        case = Case(self.base.plant.replace(**plant_changes), self.base.sensors.replace(**sensor_changes))
        for e in self.effects:
            if e.name not in without:
                case = e.apply(case, vals[e.name])
        return case

    def with_effect(self, effect: Effect) -> ModelSpace:
        """This space plus one effect's value as an extra free parameter (searched over the effect's bounds)."""
        if effect.name in self.effect_names:
            raise ValueError(f"effect {effect.name!r} is already in this space")
        lo, hi = effect.bounds
        log = effect.name in LOG_SCALED_EFFECTS and lo > 0
        return replace(
            self,
            params=(*self.params, FreeParameter(effect.name, lo, hi, effect.unit, log)),
            effects=(*self.effects, effect),
        )

    def with_effects(self, effects: Sequence[Effect]) -> ModelSpace:
        """This space plus several effects' values (see :meth:`with_effect`)."""
        space = self
        for e in effects:
            space = space.with_effect(e)
        return space


class BoundsError(ValueError):
    """Raised for a search box that cannot be searched; the message says what to fix."""


Bounds = Mapping[str, tuple[float, float] | tuple[float, float, str]]


def nominal_ratios(drive: DriveDescription = REFERENCE_DRIVE) -> dict[str, float]:
    """How each calibrated parameter's intervals scale on a drive: its nominal value over MODEL.md's [-].

    ``name -> drive nominal / BOX_NOMINALS[name]`` for K, J1, c and c1, exactly 1 for the reference; c1 follows c
    when the drive has no absorber discontinuity, and c and c1 keep MODEL.md's intervals (ratio 1) when it has
    no absorber viscosity either (an interval must have a width).
    """
    ratio = {n: float(getattr(drive, n)) / BOX_NOMINALS[n] for n in CALIBRATED}
    if not drive.c > 0:
        ratio["c"] = 1.0
    if not drive.c1 > 0:
        ratio["c1"] = ratio["c"]
    return ratio


def drive_bounds(drive: DriveDescription = REFERENCE_DRIVE) -> dict[str, tuple[float, float, str]]:
    """The default search box of a drive: :data:`DEFAULT_BOUNDS` scaled to the drive's nominal values.

    Each interval is multiplied by the drive's nominal value over MODEL.md's (:func:`nominal_ratios`): K 0.2-3x
    the nominal width, J1 0.69-1.38x the nominal inertia, c 0.5-2x the nominal viscosity, c1 0-3x the nominal
    discontinuity (0-0.6 x c [pu] when the drive has none; MODEL.md's 0.5-2.0 pu and 0-0.6 pu when it has neither
    viscosity nor discontinuity, as a box must have a width). The reference drive's ratios are exactly 1, so its
    box is :data:`DEFAULT_BOUNDS` to the bit.

    Parameters
    ----------
    drive : DriveDescription
        The drive (default MODEL.md's reference plant).

    Returns
    -------
    dict of str to (float, float, str)
        ``name -> (low, high, unit)`` for every parameter of :data:`CALIBRATED`.
    """
    ratio = nominal_ratios(drive)
    return {n: (lo * ratio[n], hi * ratio[n], unit) for n, (lo, hi, unit) in DEFAULT_BOUNDS.items()}


def check_bounds(
    bounds: Bounds | None, drive: DriveDescription = REFERENCE_DRIVE
) -> dict[str, tuple[float, float, str]]:
    """The complete search box: the drive's default box (:func:`drive_bounds`) overridden by ``bounds``, checked.

    Parameters
    ----------
    bounds : mapping or None
        Search interval per calibrated parameter, ``name -> (low, high)`` or
        ``(low, high, unit)`` in the parameter's unit (K [m], J1 [kg m^2], c [pu],
        c1 [pu]); parameters not given keep their default interval. A unit, when
        given, must be the parameter's.
    drive : DriveDescription
        The drive searched (default MODEL.md's reference plant): its box and its nominal plant, on which the
        physical limits are checked.

    Returns
    -------
    dict of str to (float, float, str)
        Every parameter of :data:`CALIBRATED`.

    Raises
    ------
    BoundsError
        For an unknown name, a wrong unit, a non-finite bound, ``low >= high``, or a
        bound outside the physical limits of :meth:`engine.simulation.PlantParameters.validate`.
    """
    out = drive_bounds(drive)
    for name, interval in (bounds or {}).items():
        if name not in DEFAULT_BOUNDS:
            raise BoundsError(
                f"unknown calibrated parameter {name!r} in the bounds; expected one of {list(CALIBRATED)}"
            )
        unit = DEFAULT_BOUNDS[name][2]
        if len(interval) not in (2, 3):
            raise BoundsError(f"bounds of {name} must be (low, high) or (low, high, unit), got {interval!r}")
        if len(interval) == 3 and interval[2] != unit:
            raise BoundsError(f"bounds of {name} must be in {unit!r}, got {interval[2]!r}")
        try:
            lo, hi = float(interval[0]), float(interval[1])
        except (TypeError, ValueError):
            raise BoundsError(f"bounds of {name} must be numbers, got {interval!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise BoundsError(f"bounds of {name} must be finite, got ({lo}, {hi})")
        if lo >= hi:
            raise BoundsError(f"lower bound of {name} must be below its upper bound, got ({lo:g}, {hi:g}) {unit}")
        for v in (lo, hi):
            try:
                drive.plant(**{name: v}).validate()
            except ParameterError as err:
                raise BoundsError(f"bounds of {name} outside the physical limits: {err}") from None
        if name in LOG_SCALED_PARAMETERS and lo <= 0:
            raise BoundsError(f"lower bound of {name} must be positive (it is searched on a log scale), got {lo:g}")
        out[name] = (lo, hi, unit)
    return out


def default_space(
    record: Record, bounds: Bounds | None = None, drive: DriveDescription = REFERENCE_DRIVE
) -> ModelSpace:
    """Parameter space of a record: K, J1, c, c1 are free unless its conditions fix them.

    Parameters
    ----------
    record : Record
        Its ``conditions`` may fix ``K`` [m], ``J1`` [kg m^2], ``c`` [pu], ``c1`` [pu]
        (and any other ``PlantParameters`` field, which is then applied as known).
        When its event was located from the data, the event instant within the
        located interval is free too (:data:`ALIGNMENT`, last).
    bounds : mapping, optional
        Search interval per calibrated parameter, ``name -> (low, high)`` or ``(low, high,
        unit)``, in the parameter's unit; parameters not given keep the drive's box
        (:func:`drive_bounds`; :data:`DEFAULT_BOUNDS` for the reference, see :func:`check_bounds`). Bounds of a
        parameter the conditions fix are checked but unused.
    drive : DriveDescription
        The drive the record was measured on (default MODEL.md's reference plant): its nominal plant is the
        space's base.

    Returns
    -------
    ModelSpace
        Without an effect.

    Raises
    ------
    BoundsError
        When the bounds are invalid (:func:`check_bounds`).
    """
    box = check_bounds(bounds, drive)
    plant_fields = set(PlantParameters.__dataclass_fields__)
    known = {k: v for k, v in record.conditions.items() if k in plant_fields}
    base = Case(drive.plant(**known))
    free = tuple(
        FreeParameter(name, box[name][0], box[name][1], box[name][2], name in LOG_SCALED_PARAMETERS)
        for name in CALIBRATED
        if name not in known
    )
    if record.event_location is not None:
        lo, hi = record.event_location.interval
        free = (*free, FreeParameter(ALIGNMENT, lo, hi, "s"))
    return ModelSpace(base, free, drive=drive)


_SENSOR_FIELDS = frozenset(SensorParameters.__dataclass_fields__)
