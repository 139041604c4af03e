"""An FMU plant's simulations on several processes, so that one diagnosis uses every core.

An FMU's simulation is a Python loop of FMI calls (one step per sample), which holds Python's lock
for most of its time: on threads, two simulations ran 0.68-0.98x as fast as one (2 cores). So
:class:`SimulationPool` keeps ``n`` worker processes, each with its own copy of the plant (built
from the same description, its FMU already built), and :meth:`FmuPlant.simulate
<engine.plants.fmu.plant.FmuPlant.simulate>` hands each simulation to one of them and waits for it
with the lock released. The diagnosis's threads (:func:`engine.diagnosis.plant_gap.simulation_pool`)
then run ``n`` simulations at once. Each simulation sends its record, values and inputs (a few tens
of kB) and gets the channels back; every result is the one the calling process would compute (the
same FMU, the same inputs).

Workers are started with ``spawn`` (a fork of a process that runs threads may copy a held lock) and
live as long as the pool; a worker that dies makes the pool raise, and a new pool is made on the next
call.
"""

from __future__ import annotations

import logging
import multiprocessing
import threading
from collections.abc import Mapping
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["SimulationPool"]

log = logging.getLogger(__name__)

#: The worker process's own plant (set by :func:`_start`).
_PLANT: Any = None


def _start(description: dict[str, Any], base_dir: str, build_dir: str | None) -> None:
    """Worker initialiser: the plant of ``description``, one process, no pool of its own."""
    global _PLANT
    from engine.plants.fmu.description import parse_description
    from engine.plants.fmu.plant import FmuPlant

    _PLANT = FmuPlant(
        parse_description(description), Path(base_dir), None if build_dir is None else Path(build_dir), processes=1
    )


def _simulate(
    name: str,
    t: np.ndarray,
    columns: dict[str, np.ndarray],
    values: dict[str, float],
    inputs: dict[str, np.ndarray] | None,
) -> dict[str, np.ndarray]:
    """Worker: one simulation of the record ``(t, columns)`` at ``values`` with ``inputs``."""
    from engine.plants.fmu.record import FmuRecord

    return _PLANT.simulate(FmuRecord(name, t, columns), values, inputs)


class SimulationPool:
    """``n`` worker processes simulating one FMU plant (module docstring).

    Parameters
    ----------
    description : mapping
        The plant's description as a document (``PlantDescription.model_dump()``).
    base_dir : Path
        The folder the description's paths start from.
    build_dir : Path, optional
        Where the FMU was built (the workers find it there).
    n : int
        Worker processes (>= 2).
    """

    def __init__(self, description: Mapping[str, Any], base_dir: Path, build_dir: Path | None, n: int) -> None:
        if n < 2:
            raise ValueError(f"a simulation pool needs at least 2 processes, got {n}")
        self._args = (dict(description), str(base_dir), None if build_dir is None else str(build_dir))
        self.n = n
        self._lock = threading.Lock()
        self._executor: ProcessPoolExecutor | None = None

    def _pool(self) -> ProcessPoolExecutor:
        with self._lock:
            if self._executor is None:
                self._executor = ProcessPoolExecutor(
                    self.n, mp_context=multiprocessing.get_context("spawn"), initializer=_start, initargs=self._args
                )
                log.info("started %d simulation processes", self.n)
            return self._executor

    def simulate(
        self, record: Any, values: Mapping[str, float], inputs: Mapping[str, np.ndarray] | None
    ) -> dict[str, np.ndarray]:
        """One simulation on a worker (its exceptions raised here, with their messages)."""
        pool = self._pool()
        future = pool.submit(
            _simulate,
            record.name,
            record.t,
            dict(record.columns),
            dict(values),
            None if inputs is None else dict(inputs),
        )
        try:
            return future.result()
        except BrokenProcessPool:
            self.close()
            raise RuntimeError(
                "a simulation process of the FMU plant died (see the log); the next call starts new ones"
            ) from None

    def close(self) -> None:
        """Stop the workers (a later call starts new ones)."""
        with self._lock:
            executor, self._executor = self._executor, None
        if executor is not None:
            executor.shutdown(wait=False, cancel_futures=True)
