"""Benchmark: many-case work on Dask, 1 against 2 local workers, and Dask's per-task overhead against a process pool.

    .venv/bin/python bench/bench_dask.py [n_cases] [n_tasks]

1. Scaling: the same ``n_cases`` protocol-2 validation (clean cases: real diagnoses of a few
   seconds each; seed 5) on local clusters of 1 and 2 single-threaded workers, cluster start-up
   included and reported apart; prints cases per second and the ratio 2 workers / 1 worker.
2. Overhead: ``n_tasks`` tasks that do nothing but return their argument, through a Dask local
   cluster and through a ``concurrent.futures.ProcessPoolExecutor`` of the same size (the pool the
   project used before Dask, kept here as the baseline only), in the same process; prints the
   seconds per task of each and their ratio.

Speed is measured here, never timed in tests.
"""

from __future__ import annotations

import logging
import multiprocessing
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from engine.distributed import dask_client, map_cases
from engine.validation.run import run_validation


def _identity(x: int) -> int:
    return x


def scaling(n_cases: int) -> dict[int, float]:
    """Cases per second of the same validation on 1 and 2 local workers (start-up included)."""
    rates = {}
    for workers in (1, 2):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            run_validation(n_cases, 5, Path(tmp) / "run", workers=workers, mix={"clean": 1.0})
            rates[workers] = n_cases / (time.perf_counter() - t0)
    return rates


def startup(workers: int) -> float:
    """Seconds to start and stop a local cluster of ``workers`` (part of every run's wall time)."""
    t0 = time.perf_counter()
    with dask_client(None, workers):
        pass
    return time.perf_counter() - t0


def overhead(n_tasks: int, workers: int = 2) -> tuple[float, float]:
    """Seconds per trivial task on Dask and on a process pool of the same size (each after its start-up)."""
    with dask_client(None, workers) as client:
        list(map_cases(client, _identity, {"warm": (0,)}, "warm"))
        t0 = time.perf_counter()
        list(map_cases(client, _identity, {str(i): (i,) for i in range(n_tasks)}, "task"))
        dask_per_task = (time.perf_counter() - t0) / n_tasks
    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        pool.submit(_identity, 0).result()
        t0 = time.perf_counter()
        for f in [pool.submit(_identity, i) for i in range(n_tasks)]:
            f.result()
        pool_per_task = (time.perf_counter() - t0) / n_tasks
    return dask_per_task, pool_per_task


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    n_cases = int(argv[0]) if argv else 8
    n_tasks = int(argv[1]) if len(argv) > 1 else 500
    rates = scaling(n_cases)
    boot = {w: startup(w) for w in (1, 2)}
    dask_t, pool_t = overhead(n_tasks)
    out = [
        f"validation of {n_cases} clean protocol-2 cases (real diagnoses), local cluster start-up included:",
        f"  1 worker : {rates[1]:.3f} cases/s",
        f"  2 workers: {rates[2]:.3f} cases/s",
        f"  scaling ratio 2/1: {rates[2] / rates[1]:.2f}",
        f"local cluster start-up and shutdown: 1 worker {boot[1]:.1f} s, 2 workers {boot[2]:.1f} s",
        f"per-task overhead, {n_tasks} trivial tasks on 2 workers: Dask {dask_t * 1e3:.2f} ms, "
        f"process pool {pool_t * 1e3:.2f} ms, ratio Dask/pool {dask_t / pool_t:.1f}",
    ]
    sys.stdout.write("\n".join(out) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
