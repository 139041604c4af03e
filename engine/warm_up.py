"""Compile the numba kernels into their cache once: ``python -m engine.warm_up``.

numba compiles a kernel the first time a process calls it and keeps the machine code beside its source
(``cache=True``), where every later process loads it in well under a second. From a fresh checkout the
backlash drive's serial kernel takes about 15 s of one core to compile (three minutes until its helpers stopped
being inlined, 2026-11-29); two processes that start cold both compile it. ``make test`` therefore runs this module once, beside the linters
and the documentation build, before the test workers start. The container image runs this module in its
build (``Dockerfile``), so that its first request is fast.

What it runs: one simulation of MODEL.md's reference case on the serial kernel and a batch of two on the
parallel one, the EMPS plant on the first second of its shipped record, the BRFD friction element and reversal
finder on its example record, the speed quantum's lattice scan and a two-epoch training of the paper's network.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from importlib.resources import files

logger = logging.getLogger(__name__)


def _drive() -> None:
    from engine.simulation import PlantParameters, simulate, simulate_batch

    simulate(PlantParameters())
    simulate_batch([PlantParameters(), PlantParameters(K=0.005)])


def _emps() -> None:
    from engine.plants.emps import EmpsPlant, load_mat

    record = load_mat(str(files("engine.plants.emps") / "data" / "DATA_EMPS.mat")).head(1.0)
    EmpsPlant().simulate(record, {})


def _brfd() -> None:
    from engine.plants.brfd import BrfdPlant

    plant = BrfdPlant()
    record = plant.example(seconds=2.0)
    plant.simulate(record, {"backlash": 0.003})
    plant.events(record)


def _diagnosis_and_network() -> None:
    import numpy as np

    from engine.diagnosis.quantisation import lattice_quantum
    from engine.identification._network import initial_weights, train

    lattice_quantum(np.repeat(np.arange(40.0), 8), (0.5, 5.0))
    train(initial_weights(np.full(3, 0.1), 4, 3, 2), np.zeros((5, 4)), np.zeros(2), 0.1, 1.0, 2)


#: The steps, by name, in the order they run.
STEPS: dict[str, Callable[[], None]] = {
    "backlash drive": _drive,
    "EMPS": _emps,
    "BRFD": _brfd,
    "speed quantum and the paper's network": _diagnosis_and_network,
}


def warm_up() -> dict[str, float]:
    """Run every step of :data:`STEPS`; return each one's wall time [s] (compiling, or loading from the cache)."""
    seconds: dict[str, float] = {}
    for name, step in STEPS.items():
        t0 = time.perf_counter()
        step()
        seconds[name] = time.perf_counter() - t0
        logger.info("numba kernels of the %s ready in %.1f s", name, seconds[name])
    return seconds


def main() -> None:
    """Entry point of ``python -m engine.warm_up``."""
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    warm_up()


if __name__ == "__main__":
    main()
