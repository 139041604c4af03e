"""The plant interface: what the gap diagnosis needs to know of a plant, and nothing more.

A plant (in the manner of motulator's subsystems, reduced to what a diagnosis reads) declares

- its **channels**: the measured signals a record holds, each with its unit;
- its **calibrated parameters**: the ones uncertain in practice, each with a nominal value and a
  plausible search interval (the diagnosis refits them with every candidate effect);
- its **catalogue** of candidate effects: named one-scalar extensions of the model (the shape of
  pysindy's feature libraries), each acting at one **locus**, a part of the plant;
- its **held-back family**: effects outside the catalogue, at each locus, kept for scoring the
  open world (a synthetic record may carry one; the diagnosis never names them), and a **sealed
  family** of the same kind whose scores development never reads (a blind run scores it once);
- its **entries**: additive inputs its simulation accepts (a force on a mass, a displacement, a
  sensor's error), and per locus the **signals** a missing term there would follow
  (:class:`LocusSignal`): what the locus estimate of an unexplained gap reads;
- the record's sample instants and the instants of its known input **events** (a pulse, a switch-off);
- its **example records**: records shipped with the package (real or of its reference test), on
  whose inputs the synthetic check of the diagnosis (:mod:`engine.validation.plant_check`) runs;
- where its **calibration starts** on a record (nominal values, or a global search's result);
- its sensors' **noise** on a record: per channel, its level and correlation time
  (:class:`engine.plants.noise.NoiseLevel`), against which a fit's residual is noise or a gap;
- how to obtain the **measured** channels from one of its records, and how to **simulate** the record's channels on the record's own grid for given parameter and effect
  values (names not given keep their nominal or neutral value).

Every plant is one module plus its catalogue, registered in :mod:`engine.plants`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from engine.plants.noise import NoiseLevel

__all__ = [
    "CalibratedParameter",
    "CandidateEffect",
    "Channel",
    "FreeParameter",
    "LocusSignal",
    "Plant",
    "checked_inputs",
    "difference_step",
    "free_parameters",
    "relative_error",
    "relative_errors",
    "retimed_instants",
    "within_span",
]


@dataclass(frozen=True)
class Channel:
    """One measured signal.

    Parameters
    ----------
    name : str
        Name used in responses (e.g. ``position``).
    unit : str
        Unit of its samples.
    description : str
        What it is and how it is obtained from the raw record.
    """

    name: str
    unit: str
    description: str = ""


@dataclass(frozen=True)
class FreeParameter:
    """One fitted parameter and its search interval.

    Parameters
    ----------
    name : str
        Parameter or effect name (e.g. the backlash drive's ``K``, ``J1``, ``c``, ``c1``).
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
class CalibratedParameter(FreeParameter):
    """A plant parameter the diagnosis refits: a :class:`FreeParameter` with a nominal value.

    Parameters
    ----------
    name, lo, hi, unit, log
        As :class:`FreeParameter` (``lo``, ``hi``: the plausible search interval).
    nominal : float
        Its nominal value, in ``unit`` (the start of a calibration), within the interval.
    """

    nominal: float = math.nan

    def __post_init__(self) -> None:
        if not (self.lo < self.hi) or (self.log and self.lo <= 0.0):
            raise ValueError(f"parameter {self.name!r}: bad search interval [{self.lo}, {self.hi}]")
        if not math.isfinite(self.nominal):
            raise ValueError(f"parameter {self.name!r}: give its nominal value")


@dataclass(frozen=True)
class CandidateEffect:
    """One candidate unmodelled effect with one scalar parameter.

    Parameters
    ----------
    name : str
        Catalogue name.
    description : str
        What it models, with the scalar's meaning and unit.
    bounds : tuple of float
        Range searched, in ``unit``.
    neutral : float
        Value at which the model is unchanged.
    unit : str
        Unit of the scalar.
    locus : str
        Part of the plant where it acts (one of the plant's loci).
    log : bool
        Search on a logarithmic scale.
    """

    name: str
    description: str
    bounds: tuple[float, float]
    neutral: float
    unit: str
    locus: str
    log: bool = False

    def as_parameter(self) -> CalibratedParameter:
        """The effect's scalar as a searched parameter (its nominal is the neutral value)."""
        lo, hi = self.bounds
        return CalibratedParameter(self.name, lo, hi, self.unit, self.log, nominal=self.neutral)


@dataclass(frozen=True, eq=False)
class LocusSignal:
    """A space of missing terms at one locus: an additive input that follows one of the plant's signals.

    The missing term is ``d(t) = factor(t) f(s(t))`` added at the plant's input ``entry``, with
    ``s`` the signal and ``f`` an unknown smooth function (the locus estimate,
    :mod:`engine.diagnosis.plant_locus`, expands it in hat functions over the signal's range, or
    in harmonics of a periodic signal). E.g. on a positioning axis a force following the velocity
    is a friction law at the guides; one following the position is an external load.

    Parameters
    ----------
    locus : str
        The part of the plant (one of the plant's loci).
    entry : str
        The additive input it enters by (a key of the plant's ``entries``).
    signal : str
        Name of the signal (e.g. ``velocity``), as the answer states it.
    unit : str
        Unit of the signal.
    values : ndarray, shape (n,)
        The signal on the record's grid, from the calibrated model (or measured).
    factor : ndarray, shape (n,), optional
        A known multiplier of ``f`` (e.g. the direction of motion for a friction level, the force
        for a gain); None for 1.
    factor_name : str
        What the factor is, for the answer.
    period : float, optional
        The signal's period in its unit when it is an angle or a phase (harmonics, not hats).
    """

    locus: str
    entry: str
    signal: str
    unit: str
    values: np.ndarray
    factor: np.ndarray | None = None
    factor_name: str = ""
    period: float | None = None


@runtime_checkable
class Plant(Protocol):
    """What the diagnosis knows of a plant (see the module docstring).

    Attributes
    ----------
    name : str
        Registry name (``--plant`` of the CLI, ``"plant"`` of the API).
    loci : tuple of str
        The parts of the plant where an effect may act.
    channels : tuple of Channel
        The measured signals, in order.
    calibrated : tuple of CalibratedParameter
        Parameters refitted with every candidate effect.
    catalogue : mapping of str to CandidateEffect
        The candidate effects.
    held_back : mapping of str to CandidateEffect
        Effects outside the catalogue, kept for scoring the diagnosis of a gap the catalogue cannot
        explain (:meth:`simulate` accepts their names; the diagnosis never fits them). May be empty.
    sealed : mapping of str to CandidateEffect
        A second family of the same kind, defined before any diagnosis ran on it, whose scores
        development never reads. May be empty.
    entries : mapping of str to str
        Additive inputs :meth:`simulate` accepts (``inputs=``), name -> unit. May be empty.
    diff_step : float
        Step of the diagnosis' finite differences, as a share of each parameter's search interval:
        the smallest step at which the plant's simulated channels change smoothly (a simulation
        with stick-slip friction is rough on fine scales; a smooth one wants a fine step).
    concurrent : bool
        Whether :meth:`simulate` may run on several threads at once and spends its time with the GIL
        released (a ``nogil`` kernel, no shared mutable state): the diagnosis then runs its
        independent simulations (finite-difference columns, scans, the locus's responses) on a pool of
        threads (:func:`engine.diagnosis.plant_gap.simulation_pool`). False for a plant whose
        simulation parallelises itself (the backlash drive's batched kernel) or holds the GIL.
    """

    name: str
    loci: tuple[str, ...]
    channels: tuple[Channel, ...]
    calibrated: tuple[CalibratedParameter, ...]
    catalogue: Mapping[str, CandidateEffect]
    held_back: Mapping[str, CandidateEffect]
    sealed: Mapping[str, CandidateEffect]
    entries: Mapping[str, str]
    diff_step: float
    concurrent: bool

    def measured(self, record: Any) -> dict[str, np.ndarray]:
        """The record's measured channels, ``name -> samples`` in channel order and unit."""
        ...

    def simulate(
        self, record: Any, values: Mapping[str, float], inputs: Mapping[str, np.ndarray] | None = None
    ) -> dict[str, np.ndarray]:
        """The channels simulated on the record's grid with its inputs.

        ``values`` holds calibrated parameters, effect scalars and held-back effect scalars by
        name; a name not given keeps its nominal (parameters) or neutral (effects) value.
        ``inputs`` adds schedules (one value per sample of the record, in the entry's unit) at
        the plant's :attr:`entries`. Raises on an unknown name or entry and on solver failure.
        """
        ...

    def locus_signals(self, record: Any, values: Mapping[str, float]) -> tuple[LocusSignal, ...]:
        """Per locus, the signals a missing term there would follow, on ``record``'s grid at ``values``.

        The plant's statement of what each of its parts sees (:class:`LocusSignal`); empty for a
        plant whose locus estimate is its own (the backlash drive's :mod:`engine.diagnosis.locus`).
        """
        ...

    def scored(self, record: Any) -> slice:
        """The samples a comparison scores (e.g. without a filter's edge)."""
        ...

    def fixed_by(self, record: Any) -> Mapping[str, float]:
        """Calibrated parameters whose values the record itself fixes (its known conditions).

        The diagnosis neither fits them nor passes them to :meth:`simulate`; see :func:`free_parameters`.
        """
        ...

    def noise(self, record: Any) -> Mapping[str, NoiseLevel]:
        """The noise the plant's sensors add to each channel of ``record``, over its scored samples.

        The plant's noise model: what a residual at noise level looks like on this record. A real
        record's residual is mostly model error, far above it; a synthetic record's (from
        :meth:`synthesize`) reaches it when the model is right. Raises ``ValueError`` for a channel
        whose level cannot be estimated (too short, not finite, zero throughout).
        """
        ...

    def calibration_start(self, record: Any) -> Mapping[str, float] | None:
        """Where the calibration's local least squares starts on ``record``, or None for the nominal values.

        A plant whose calibration cost has local minima near its nominal values (the backlash drive's
        strongly nonlinear test) gives a global search's result; a plant whose cost is well behaved
        from nominal (EMPS, BRFD) returns None. Names are calibrated parameters the record leaves free.
        """
        ...

    def synthesize(self, record: Any, values: Mapping[str, float], rng: np.random.Generator) -> Any:
        """A record as the plant's sensors would give it, simulated at ``values`` on ``record``'s inputs and grid.

        For a synthetic check of the diagnosis (:mod:`engine.validation.plant_check`): the
        answer is a record like ``record`` (same grid, same inputs) whose measured signals are the
        simulation's, with the plant's own measurement imperfections drawn from ``rng``.
        """
        ...

    def events(self, record: Any) -> np.ndarray:
        """Instants [s] on the record's time axis where a known input changes abruptly (may be empty)."""
        ...

    def retimed(self, record: Any, factor: float) -> Any:
        """The record read with its sample interval multiplied by ``factor``, the samples unchanged.

        The reading a record with a wrongly declared interval would have had (``factor`` 0.1: the
        declared interval was 10x too long), for the plausibility check of the sample interval
        (:func:`engine.diagnosis.plant_plausibility.check_interval`); the first instant stays where it is.

        Raises
        ------
        ValueError
            When the plant cannot read the record at that interval (its records have one fixed grid,
            which its reader enforces, or the interval leaves the range its simulation accepts).
        """
        ...

    def time(self, record: Any) -> np.ndarray:
        """The record's sample instants [s]."""
        ...

    def near_events(self, record: Any) -> np.ndarray:
        """Per sample, whether it lies in the transient of one of the record's input events.

        What "near" means is the plant's: a time span around each event (:func:`within_span`), or
        a stretch of travel after a reversal. The diagnosis reports how much of the residual lies
        there beside the share of samples there.
        """
        ...

    @property
    def examples(self) -> tuple[str, ...]:
        """Names of the records :meth:`example` gives, the first one the default."""
        ...

    def example(self, name: str | None = None, seconds: float | None = None) -> Any:
        """A record shipped with the package (default the first of :attr:`examples`).

        ``seconds`` keeps the record's first seconds where the plant's records can be cut (a long
        real record); a plant whose records are one short test ignores it.

        Raises
        ------
        KeyError
            For a name not in :attr:`examples`.
        """
        ...


def within_span(t: np.ndarray, events: np.ndarray, span: tuple[float, float]) -> np.ndarray:
    """Samples at instants ``t`` [s] from ``span[0]`` to ``span[1]`` [s] around any of ``events`` [s]."""
    t = np.asarray(t, dtype=float)
    near = np.zeros(t.size, dtype=bool)
    for te in np.asarray(events, dtype=float):
        near |= (t >= te + span[0]) & (t < te + span[1])
    return near


def retimed_instants(t: np.ndarray, factor: float) -> np.ndarray:
    """Sample instants ``t`` [s] read with their interval multiplied by ``factor``, the first instant kept.

    What :meth:`Plant.retimed` does to a record's time axis. Raises ``ValueError`` for a factor that
    is not a positive finite number.
    """
    if not (math.isfinite(factor) and factor > 0.0):
        raise ValueError(f"a sample interval's factor must be a positive number, got {factor}")
    t = np.asarray(t, dtype=float)
    return t[0] + factor * (t - t[0])


def free_parameters(plant: Plant, record: Any) -> tuple[CalibratedParameter, ...]:
    """The plant's calibrated parameters the record leaves free (not in :meth:`Plant.fixed_by`)."""
    fixed = plant.fixed_by(record)
    return tuple(p for p in plant.calibrated if p.name not in fixed)


def difference_step(p: FreeParameter, value: float, h: float) -> tuple[float, float]:
    """A finite-difference step of ``p`` at ``value`` in its unit box: ``(u, step)``.

    ``u`` is the value's unit coordinate; ``step`` is ``h``, or ``-h`` where a forward step would leave
    the box. The value stepped is ``p.value(u + step)``.
    """
    u = p.unit_coord(value)
    return u, (h if u + h <= 1.0 else -h)


def checked_inputs(
    plant: str, entries: Mapping[str, str], n: int, inputs: Mapping[str, np.ndarray] | None
) -> dict[str, np.ndarray]:
    """Additive input schedules checked against a plant's entries and a record of ``n`` samples.

    Raises
    ------
    KeyError
        For a name not in ``entries``.
    ValueError
        For a schedule that is not ``n`` finite values.
    """
    out: dict[str, np.ndarray] = {}
    for name, schedule in (inputs or {}).items():
        if name not in entries:
            raise KeyError(f"unknown {plant} entry {name!r}; entries: {', '.join(entries)}")
        x = np.asarray(schedule, dtype=float)
        if x.shape != (n,):
            raise ValueError(
                f"{plant} input {name!r} needs {n} finite samples, one per sample of the record; got shape {x.shape}"
            )
        if not np.all(np.isfinite(x)):
            raise ValueError(f"{plant} input {name!r} has non-finite values; it needs {n} finite samples")
        out[name] = x
    return out


def relative_error(measured: np.ndarray, simulated: np.ndarray) -> float:
    """Relative error ``100 ||y - y_hat|| / ||y||`` [%] (Janot et al., EMPS report, eq. 11).

    Raises
    ------
    ValueError
        For arrays of different shapes or a measured signal of zero norm.
    """
    y = np.asarray(measured, dtype=float)
    yh = np.asarray(simulated, dtype=float)
    if y.shape != yh.shape:
        raise ValueError(f"relative error of arrays of shapes {y.shape} and {yh.shape}")
    norm = float(np.linalg.norm(y))
    if norm == 0.0:
        raise ValueError("relative error of a signal that is zero throughout")
    return 100.0 * float(np.linalg.norm(y - yh)) / norm


def relative_errors(
    measured: Mapping[str, np.ndarray], simulated: Mapping[str, np.ndarray], window: slice = slice(None)
) -> dict[str, float]:
    """:func:`relative_error` [%] of every measured channel over the samples ``window``."""
    return {name: relative_error(y[window], simulated[name][window]) for name, y in measured.items()}
