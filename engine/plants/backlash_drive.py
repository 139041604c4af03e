"""The backlash drive of MODEL.md as a :class:`~engine.plants.base.Plant`.

A thin adapter over :mod:`engine.simulation` and :mod:`engine.diagnosis.space`: its calibrated
parameters are the search box of :data:`engine.diagnosis.space.DEFAULT_BOUNDS` (K, J1, c, c1),
its catalogue :data:`engine.simulation.CATALOGUE`, its loci :data:`engine.simulation.LOCI`, and a
record is a :class:`engine.records.Record` simulated on its own grid (the calibration's own model
space, so conditions a record fixes stay fixed).
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType

import numpy as np

from engine.constants import CHANNEL_UNITS, CHANNELS
from engine.diagnosis.space import DEFAULT_BOUNDS, LOG_SCALED_EFFECTS, LOG_SCALED_PARAMETERS, default_space
from engine.plants.base import CalibratedParameter, CandidateEffect, Channel, LocusSignal, within_span
from engine.plants.noise import NoiseLevel, white_noise_level
from engine.records import Record
from engine.simulation import (
    CATALOGUE,
    LOCI,
    PlantParameters,
    SimulationError,
    SolverSettings,
    add_white_noise,
    run_cases,
    simulate,
)

__all__ = ["DIFF_STEP", "SYNTHETIC_SNR_DB", "BacklashDrivePlant"]

#: Step of the diagnosis' finite differences, as a share of a parameter's interval. The kernel is
#: smooth in its parameters: with the EMPS plant's 1e-2 a fit of J1 and a rotor-resistance drift of
#: 1.3 stopped at 0.87 / 1.25 (a1 error 16 % left on a 40 dB record); with 1e-3 it reached the
#: noise (0.90 / 1.30, a1 error 1.1 %, tests/test_plants.py).
DIFF_STEP: float = 1e-3

#: The backlash test's transient around its event t_e [s]: from 5 ms before to 50 ms after.
EVENT_SPAN: tuple[float, float] = (-0.005, 0.05)

#: Signal-to-noise ratio of a synthetic record's white noise [dB] (the middle of MODEL.md's 30-50 dB).
SYNTHETIC_SNR_DB: float = 40.0


def _nominal(name: str) -> float:
    lo, hi, _ = DEFAULT_BOUNDS[name]
    v = float(getattr(PlantParameters(), name))
    return min(max(v, lo), hi)


class BacklashDrivePlant:
    """The reference plant (MODEL.md) behind the plant interface."""

    name: str = "backlash_drive"
    loci: tuple[str, ...] = LOCI
    channels: tuple[Channel, ...] = tuple(Channel(c, CHANNEL_UNITS[c]) for c in CHANNELS)
    calibrated: tuple[CalibratedParameter, ...] = tuple(
        CalibratedParameter(n, lo, hi, unit, n in LOG_SCALED_PARAMETERS, nominal=_nominal(n))
        for n, (lo, hi, unit) in DEFAULT_BOUNDS.items()
    )
    catalogue: Mapping[str, CandidateEffect] = MappingProxyType(
        {
            n: CandidateEffect(e.name, e.description, e.bounds, e.neutral, e.unit, e.locus, n in LOG_SCALED_EFFECTS)
            for n, e in CATALOGUE.items()
        }
    )

    #: Protocol 2's families (:data:`engine.simulation.HELD_BACK`, ``SEALED``) score this plant's open
    #: world through its own validation, not through the plant interface: none here.
    held_back: Mapping[str, CandidateEffect] = MappingProxyType({})
    sealed: Mapping[str, CandidateEffect] = MappingProxyType({})
    #: The drive's unknown inputs are :class:`engine.simulation.Disturbance`, read by its own locus
    #: estimate (:mod:`engine.diagnosis.locus`): none through the interface.
    entries: Mapping[str, str] = MappingProxyType({})
    diff_step: float = DIFF_STEP
    #: The drive's simulator parallelises its own batches (numba's threads): none on the diagnosis's threads.
    concurrent: bool = False

    def __init__(self, solver: SolverSettings | None = None) -> None:
        self.solver = solver or SolverSettings()

    @property
    def examples(self) -> tuple[str, ...]:
        """``reference_test``: MODEL.md's test simulated at the nominal parameters, noise-free."""
        return ("reference_test",)

    def example(self, name: str | None = None, seconds: float | None = None) -> Record:
        """MODEL.md's reference test at :class:`~engine.simulation.PlantParameters`' nominal values.

        The record fixes no condition: a diagnosis of it calibrates K, J1, c and c1. ``seconds`` is
        ignored (the test is one short event).
        """
        if (name or "reference_test") != "reference_test":
            raise KeyError(f"unknown backlash-drive example {name!r}; known: reference_test")
        sim = simulate(PlantParameters(), solver=self.solver)
        return Record(dict(sim.channels), sim.sample_interval, sim.event_index)

    def measured(self, record: Record) -> dict[str, np.ndarray]:
        """The record's channels as given (model units)."""
        return {n: np.asarray(v, dtype=float) for n, v in record.channels.items()}

    def fixed_by(self, record: Record) -> dict[str, float]:
        """The record's conditions among K, J1, c, c1 (a condition the bench knows is not calibrated)."""
        return {p.name: float(record.conditions[p.name]) for p in self.calibrated if p.name in record.conditions}

    def scored(self, record: Record) -> slice:
        """Every sample."""
        return slice(None)

    def time(self, record: Record) -> np.ndarray:
        """Sample instants [s] relative to the event."""
        return record.time

    def retimed(self, record: Record, factor: float) -> Record:
        """The record read with its sample interval multiplied by ``factor`` (see :meth:`Plant.retimed`).

        Raises :class:`~engine.records.GridError` (a ``ValueError``) outside the accepted intervals.
        """
        return record.replace(sample_interval=factor * record.sample_interval)

    def events(self, record: Record) -> np.ndarray:
        """The record's event instant t_e (MODEL.md's backlash test; 0 on the record's time axis)."""
        return np.array([record.time[record.event_index]])

    def near_events(self, record: Record) -> np.ndarray:
        """Samples within :data:`EVENT_SPAN` of the event t_e."""
        return within_span(record.time, self.events(record), EVENT_SPAN)

    def calibration_start(self, record: Record) -> dict[str, float]:
        """The drive's own nominal calibration (:func:`engine.diagnosis.calibration.calibrate` with
        :data:`~engine.diagnosis.settings.NOMINAL_CALIBRATION`: a Sobol search, then continuation over
        growing horizons). From the nominal values alone, least squares stopped in a local minimum on
        half of the clean records of the synthetic check (seed 25, docs/real-data.md section 6)."""
        from engine.diagnosis.calibration import calibrate
        from engine.diagnosis.settings import NOMINAL_CALIBRATION

        return dict(calibrate(record, default_space(record), NOMINAL_CALIBRATION).values)

    def noise(self, record: Record) -> dict[str, NoiseLevel]:
        """Each channel's white noise, from its finest wavelet level (MODEL.md's records carry white
        noise; the drive's own diagnosis fits a coloured model too, :mod:`engine.diagnosis.noise`)."""
        return {n: white_noise_level(v[self.scored(record)]) for n, v in self.measured(record).items()}

    def synthesize(self, record: Record, values: Mapping[str, float], rng: np.random.Generator) -> Record:
        """The record's channels simulated at ``values`` plus white noise at :data:`SYNTHETIC_SNR_DB`."""
        sim = self.simulate(record, values)
        return record.with_channels({n: add_white_noise(v, SYNTHETIC_SNR_DB, rng) for n, v in sim.items()})

    def locus_signals(self, record: Record, values: Mapping[str, float]) -> tuple[LocusSignal, ...]:
        """None: the drive's locus estimate is its own (:mod:`engine.diagnosis.locus`)."""
        return ()

    def simulate(
        self, record: Record, values: Mapping[str, float], inputs: Mapping[str, np.ndarray] | None = None
    ) -> dict[str, np.ndarray]:
        """The record's channels simulated on its grid (names not given: nominal or neutral).

        A calibrated parameter the record's conditions fix keeps the record's value; another value
        for it is refused, not silently replaced.

        Raises
        ------
        KeyError
            For an unknown name.
        ValueError
            For a value of a parameter the record's conditions fix at another value.
        SimulationError
            When the simulation fails (no event, divergence).
        """
        if inputs:
            raise KeyError(f"the backlash drive takes no inputs through the plant interface, got {sorted(inputs)}")
        space = default_space(record)
        unknown = [n for n in values if n not in space.names and n not in DEFAULT_BOUNDS and n not in CATALOGUE]
        if unknown:
            raise KeyError(f"unknown backlash-drive parameter or effect(s) {unknown}")
        fixed = [n for n in values if n in record.conditions and values[n] != record.conditions[n]]
        if fixed:
            raise ValueError(
                f"the record's conditions fix {fixed} at {[record.conditions[n] for n in fixed]}; "
                "leave them out of the values or give the record's own"
            )
        effects = [CATALOGUE[n] for n in values if n in CATALOGUE]
        space = space.with_effects(effects)
        full = {n: _nominal(n) for n in DEFAULT_BOUNDS} | {e.name: e.neutral for e in effects} | dict(values)
        case = space.case(space.unit(full))
        ch, _, status = run_cases([case], self.solver, record.grid)
        if status[0] != 0:
            raise SimulationError({0: f"kernel status {int(status[0])}"})
        return {n: ch[0, CHANNELS.index(n)] for n in record.channels}
