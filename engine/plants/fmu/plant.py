"""A plant of the interface (:mod:`engine.plants.base`) from an FMU and its description (issue 55).

:class:`FmuPlant` reads the user's own simulator through its description
(:mod:`engine.plants.fmu.description`): the record's driven columns go to the FMU's inputs through
the generic actuators, the FMU's outputs come back through the generic measurement chain
(:mod:`engine.plants.fmu.generic`), the description's calibrated parameters and effects are FMU
parameters set for each simulation. Every FMU input is an entry of the plant (an additive schedule
the locus estimate may add), at the description's locus of that input; the locus estimate's
signals at each entry are the time (a missing input of any shape) and every simulated channel (a
missing term that follows what the machine does).

The diagnosis then reads it as it reads any plant (``backlash diagnose --plant path/to/plant.toml``):
calibration, the catalogue's effects and sets, the noise gate, the locus of a gap no effect explains.
"""

from __future__ import annotations

import logging
import threading
import weakref
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numba
import numpy as np

from engine.plants.base import (
    CalibratedParameter,
    CandidateEffect,
    Channel,
    LocusSignal,
    checked_inputs,
    retimed_instants,
)
from engine.plants.fmu.build import build_fmu
from engine.plants.fmu.description import DescriptionError, PlantDescription, load_description
from engine.plants.fmu.generic import GenericEffect, apply_actuators, apply_sensors, generic_effects
from engine.plants.fmu.pool import SimulationPool
from engine.plants.fmu.record import FmuRecord, load_record
from engine.plants.fmu.runner import FmuModel, FmuSimulationError
from engine.plants.noise import NoiseLevel, white_noise_level

__all__ = ["SYNTHETIC_NOISE_SHARE", "FmuPlant", "default_build_dir", "load_plant"]

log = logging.getLogger(__name__)

#: White noise of a synthetic record, as a share of each channel's RMS (40 dB).
SYNTHETIC_NOISE_SHARE: float = 0.01


def default_build_dir() -> Path:
    """Where FMUs built from sources are cached: the user's cache folder (platformdirs)."""
    from platformdirs import user_cache_dir

    return Path(user_cache_dir("backlash")) / "fmu"


class FmuPlant:
    """A plant from an FMU (module docstring).

    Parameters
    ----------
    description : PlantDescription
        What the FMU is to the diagnosis.
    base_dir : Path
        The folder the description's relative paths (the FMU, the examples) start from.
    build_dir : Path, optional
        Where an FMU given as sources is built (default :func:`default_build_dir`).
    processes : int, optional
        Worker processes the simulations run on (:mod:`engine.plants.fmu.pool`; default numba's thread
        count, the diagnosis's threads on this machine); 1 runs them in this process. With more than one
        the plant is :attr:`concurrent`: the diagnosis's threads hand it simulations at once.

    Raises
    ------
    DescriptionError
        When the FMU does not have a variable the description names (or has it with another
        causality or unit), or a generic effect's name collides with the description's.
    """

    def __init__(
        self, description: PlantDescription, base_dir: Path, build_dir: Path | None = None, processes: int | None = None
    ) -> None:
        self.description = description
        self.base_dir = Path(base_dir)
        where = self.base_dir / description.fmu
        build_dir = build_dir or default_build_dir()
        if where.is_dir():
            fmu_path = build_fmu(where, build_dir)
        elif where.is_file():
            fmu_path = where
        else:
            raise DescriptionError(
                f"plant {description.name!r}: fmu = {description.fmu!r}: no such file or folder in {self.base_dir}"
            )
        try:
            self.model = FmuModel(fmu_path, interface=description.interface)
        except ValueError as e:
            raise DescriptionError(f"plant {description.name!r}: {e}") from None
        self._check_variables()
        self.name: str = description.name
        self.loci: tuple[str, ...] = description.all_loci
        self.channels: tuple[Channel, ...] = tuple(Channel(c.name, c.unit, c.description) for c in description.channels)
        self.calibrated: tuple[CalibratedParameter, ...] = tuple(
            CalibratedParameter(c.name, c.lo, c.hi, c.unit, c.log, nominal=c.nominal) for c in description.calibrated
        )
        self._generic: dict[str, GenericEffect] = generic_effects(description)
        own = {e.name: self._effect(e) for e in description.effects}
        clash = sorted(set(own) & set(self._generic))
        if clash:
            raise DescriptionError(
                f"plant {description.name!r}: effects {clash} are named as generic effects; rename them"
            )
        self.catalogue: Mapping[str, CandidateEffect] = MappingProxyType(
            {**own, **{n: g.effect for n, g in self._generic.items()}}
        )
        self.held_back: Mapping[str, CandidateEffect] = MappingProxyType(
            {e.name: self._effect(e) for e in description.held_back}
        )
        self.sealed: Mapping[str, CandidateEffect] = MappingProxyType({})
        self.entries: Mapping[str, str] = MappingProxyType({i.variable: i.unit for i in description.inputs})
        self.diff_step: float = description.diff_step
        n = int(numba.get_num_threads()) if processes is None else int(processes)
        if n < 1:
            raise ValueError(f"processes must be at least 1, got {processes}")
        self._pool = SimulationPool(description.model_dump(), self.base_dir, build_dir, n) if n > 1 else None
        if self._pool is not None:
            weakref.finalize(self, self._pool.close)
        #: Whether the diagnosis may hand it simulations from several threads at once: when they run on
        #: worker processes (a simulation's per-sample loop holds Python's lock: threads alone gain nothing).
        self.concurrent: bool = self._pool is not None
        self._fmu_param = {c.name: c.fmu_variable for c in description.calibrated}
        self._fmu_param.update({e.name: e.fmu_variable for e in (*description.effects, *description.held_back)})
        self._neutral = {c.name: c.nominal for c in description.calibrated}
        self._neutral.update({e.name: e.neutral for e in (*description.effects, *description.held_back)})
        self._examples: dict[str, FmuRecord] = {}
        self._lock = threading.Lock()

    @staticmethod
    def _effect(e: Any) -> CandidateEffect:
        return CandidateEffect(e.name, e.description, tuple(e.bounds), e.neutral, e.unit, e.locus, e.log)

    def _check_variables(self) -> None:
        d, m = self.description, self.model

        def check(name: str, causality: str | tuple[str, ...], unit: str, what: str) -> None:
            try:
                v = m.variable(name, causality)
            except KeyError as e:
                raise DescriptionError(f"plant {d.name!r}: {what}: {e.args[0]}") from None
            if unit and v.unit and unit != v.unit:
                raise DescriptionError(
                    f"plant {d.name!r}: {what}: the description says {unit!r}, the FMU declares {v.unit!r}"
                )

        for i in d.inputs:
            check(i.variable, "input", i.unit, f"input {i.variable!r}")
        for c in d.channels:
            check(c.variable, "output", c.unit, f"channel {c.name!r}")
        for p in d.calibrated:
            check(p.fmu_variable, "parameter", p.unit, f"calibrated parameter {p.name!r}")
        for e in (*d.effects, *d.held_back):
            check(e.fmu_variable, "parameter", e.unit, f"effect {e.name!r}")

    # --- records -------------------------------------------------------------------------------------

    @property
    def examples(self) -> tuple[str, ...]:
        """The description's example records (file stems)."""
        return tuple(Path(p).stem for p in self.description.examples)

    def example(self, name: str | None = None, seconds: float | None = None) -> FmuRecord:
        """A record the description ships (the first by default); ``seconds`` is ignored.

        Raises
        ------
        KeyError
            For a name not in :attr:`examples`, or a description that ships none.
        """
        if not self.description.examples:
            raise KeyError(f"plant {self.name!r} ships no example record (its description lists none)")
        stems = dict(zip(self.examples, self.description.examples, strict=True))
        key = name or self.examples[0]
        if key not in stems:
            raise KeyError(f"unknown example {key!r} of plant {self.name!r}; shipped: {', '.join(stems)}")
        with self._lock:
            if key not in self._examples:
                self._examples[key] = self.read(self.base_dir / stems[key])
            return self._examples[key]

    def read(self, path: str | Path) -> FmuRecord:
        """A record file (CSV, :mod:`engine.plants.fmu.record`); raises ``RecordError`` with what to fix."""
        return load_record(path, self.description)

    def measured(self, record: FmuRecord) -> dict[str, np.ndarray]:
        """The record's measured channels, in the description's units."""
        return {c.name: np.asarray(record.columns[c.name], dtype=float) for c in self.channels}

    def time(self, record: FmuRecord) -> np.ndarray:
        """The record's sample instants [s]."""
        return record.t

    def scored(self, record: FmuRecord) -> slice:
        """Every sample from ``settle`` seconds after the record's first on."""
        return slice(int(np.searchsorted(record.t, record.t[0] + self.description.settle)), None)

    def fixed_by(self, record: FmuRecord) -> dict[str, float]:
        """None: a record of an FMU plant fixes no calibrated parameter."""
        return {}

    def retimed(self, record: FmuRecord, factor: float) -> FmuRecord:
        """The record read with its sample interval multiplied by ``factor`` (see :meth:`Plant.retimed`)."""
        return FmuRecord(record.name, retimed_instants(record.t, factor), record.columns)

    def events(self, record: FmuRecord) -> np.ndarray:
        """No known input events (an FMU plant's inputs are the record's columns)."""
        return np.empty(0)

    def near_events(self, record: FmuRecord) -> np.ndarray:
        """No sample lies near an event."""
        return np.zeros(record.n, dtype=bool)

    def calibration_start(self, record: FmuRecord) -> dict[str, float] | None:
        """Where the calibration starts: the best of a Sobol search over the calibrated box, when the
        description asks for one (``calibration_search`` points, the nominal point among them), else None
        (the nominal values). The search's cost is the channel-normalised residual of the diagnosis."""
        n = self.description.calibration_search
        if n == 0 or not self.calibrated:
            return None
        from scipy.stats import qmc

        from engine.diagnosis.plant_gap import PlantObjective

        objective = PlantObjective(self, record)
        points = qmc.Sobol(len(self.calibrated), scramble=True, seed=0).random(n)
        best = {p.name: p.nominal for p in self.calibrated}
        r = objective.vector(best)
        best_cost = float(r @ r)
        for u in points:
            trial = {p.name: float(p.value(ui)) for p, ui in zip(self.calibrated, u, strict=True)}
            try:
                r = objective.vector(trial)
            except FmuSimulationError:  # a corner of the box the FMU refuses is no start
                continue
            cost = float(r @ r)
            if cost < best_cost:
                best, best_cost = trial, cost
        log.info("calibration start of %s on %s: %s (cost %.4g, %d points)", self.name, record.name, best, best_cost, n)
        return best

    def noise(self, record: FmuRecord) -> dict[str, NoiseLevel]:
        """Each channel's noise, white, from the record's finest wavelet level (as the BRFD's load cell)."""
        s = self.scored(record)
        return {c.name: white_noise_level(np.asarray(record.columns[c.name], dtype=float)[s]) for c in self.channels}

    # --- simulation ----------------------------------------------------------------------------------

    def simulate(
        self, record: FmuRecord, values: Mapping[str, float], inputs: Mapping[str, np.ndarray] | None = None
    ) -> dict[str, np.ndarray]:
        """The channels simulated on the record's grid with its driven inputs.

        ``values``: calibrated parameters, the catalogue's effects (the description's and the generic
        ones) and held-back effects by name; others keep their nominal or neutral value. ``inputs``:
        additive schedules at the plant's :attr:`entries` (FMU inputs, one value per sample).

        Raises
        ------
        KeyError
            For an unknown name or entry.
        ValueError
            For an input that is not one finite value per sample.
        FmuSimulationError
            When the FMU refuses initialisation or a step (its own message included).
        """
        unknown = [n for n in values if n not in self._fmu_param and n not in self._generic]
        if unknown:
            raise KeyError(f"unknown parameter(s) or effect(s) {unknown} of plant {self.name!r}")
        extra = checked_inputs(self.name, self.entries, record.n, inputs)
        if self._pool is not None:
            return self._pool.simulate(record, values, extra)
        params = {self._fmu_param[n]: float(values.get(n, v)) for n, v in self._neutral.items()}
        driven = {
            str(i.column): np.asarray(record.columns[str(i.column)], dtype=float) for i in self.description.driven
        }
        driven = apply_actuators(self._generic, values, record.t, driven)
        fmu_inputs: dict[str, np.ndarray] = {}
        for i in self.description.inputs:
            u = driven[str(i.column)] if i.column else np.zeros(record.n)
            if i.variable in extra:
                u = u + extra[i.variable]
            if i.column or i.variable in extra:
                fmu_inputs[i.variable] = u
        y = self.model.simulate(
            record.t, self.description.start_time, params, fmu_inputs, [c.variable for c in self.description.channels]
        )
        out = {c.name: y[k] for k, c in enumerate(self.description.channels)}
        return apply_sensors(self._generic, values, record.t, out)

    def locus_signals(self, record: FmuRecord, values: Mapping[str, float]) -> tuple[LocusSignal, ...]:
        """Per FMU input (at its locus): a missing input of any shape in time, and one following each channel."""
        sim = self.simulate(record, values)
        t = record.t - record.t[0]
        out: list[LocusSignal] = []
        for i in self.description.inputs:
            out.append(LocusSignal(i.locus, i.variable, "time", "s", t))
            for c in self.channels:
                out.append(LocusSignal(i.locus, i.variable, c.name, c.unit, sim[c.name]))
        return tuple(out)

    def synthesize(self, record: FmuRecord, values: Mapping[str, float], rng: np.random.Generator) -> FmuRecord:
        """A record like ``record`` whose channels are simulated at ``values`` plus white noise (40 dB)."""
        y = self.simulate(record, values)
        noisy = {
            k: v + rng.normal(0.0, SYNTHETIC_NOISE_SHARE * float(np.sqrt(np.mean(v**2))) or 1e-12, v.size)
            for k, v in y.items()
        }
        return record.replace_columns(noisy, name=f"synthetic({record.name})")


def load_plant(path: str | Path, build_dir: Path | None = None, processes: int | None = None) -> FmuPlant:
    """The plant described by the TOML file ``path`` (its FMU built first when given as sources).

    ``build_dir`` and ``processes`` are :class:`FmuPlant`'s.

    Raises
    ------
    DescriptionError
        For a description or an FMU the plant cannot use; the message says what to fix.
    """
    path = Path(path)
    return FmuPlant(load_description(path), path.resolve().parent, build_dir, processes)
