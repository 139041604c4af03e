"""Many-case work on Dask (dask.distributed): a local cluster by default, an existing one on request.

Every many-case workload (a blind validation's diagnoses, a batch diagnosis) submits one task per
case to a :class:`distributed.Client` and collects the results in this process, which alone reads
the inputs and writes the outputs: a task gets its record and returns its answer, so workers need
no shared file system and the result of a case does not depend on where it ran.

- :func:`dask_client`: a :class:`distributed.LocalCluster` on this machine's cores (one
  single-threaded worker process per core) unless a scheduler address is given (``--scheduler``
  or the :data:`SCHEDULER_ENV` environment variable), then a client of that cluster.
- :func:`run_single_threaded`: what every task runs its function through: numba and the BLAS
  libraries limited to one thread in the worker's thread, so that N worker threads use N cores,
  whatever the workers were started with.
- :func:`map_cases`: submit, then yield ``(key, result)`` as tasks finish, with progress (a bar on a
  terminal, log lines otherwise). A worker that dies takes its tasks with it; the scheduler runs
  them again on the others (``distributed.scheduler.allowed-failures``), so a run survives the loss
  of a worker.
"""

from __future__ import annotations

import logging
import os
import sys
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any, TypeVar

__all__ = [
    "SCHEDULER_ENV",
    "Progress",
    "SchedulerUnreachable",
    "connect",
    "dask_client",
    "map_cases",
    "run_single_threaded",
    "scheduler_address",
]

logger = logging.getLogger(__name__)

#: Environment variable naming an existing scheduler (``tcp://host:port``).
SCHEDULER_ENV: str = "BACKLASH_DASK_SCHEDULER"
#: Seconds to wait for an existing scheduler to answer.
CONNECT_TIMEOUT: float = 20.0

T = TypeVar("T")


class SchedulerUnreachable(OSError):
    """The Dask scheduler named by ``--scheduler`` or :data:`SCHEDULER_ENV` does not answer."""


def scheduler_address(scheduler: str | None = None) -> str | None:
    """The scheduler to use: ``scheduler``, else :data:`SCHEDULER_ENV`, else None (a local cluster)."""
    return scheduler or os.environ.get(SCHEDULER_ENV) or None


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None) -> Iterator[Any]:
    """A Dask client: of the cluster at ``scheduler`` (or :data:`SCHEDULER_ENV`), else of a local cluster.

    Parameters
    ----------
    scheduler : str, optional
        Address of an existing scheduler, ``tcp://host:port``.
    workers : int, optional
        Worker processes of the local cluster (default: the machine's cores); 0 yields None: no
        cluster, :func:`map_cases` then runs the tasks in this process (debugging, small runs).
        Ignored with a scheduler.

    Raises
    ------
    SchedulerUnreachable
        When the scheduler cannot be reached within :data:`CONNECT_TIMEOUT` (the message names it).
    """
    from distributed import Client, LocalCluster

    address = scheduler_address(scheduler)
    if address is not None:
        client = connect(address)
        logger.info("Dask: scheduler %s, %d workers", address, len(client.scheduler_info().get("workers", {})))
        try:
            yield client
        finally:
            client.close()
        return
    if workers == 0:
        yield None
        return
    n = workers or os.cpu_count() or 1
    logging.getLogger("distributed").setLevel(max(logging.WARNING, logging.getLogger().getEffectiveLevel()))
    single = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    cluster = LocalCluster(
        n_workers=n,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        env=single,
        silence_logs=logging.WARNING,
    )
    client = Client(cluster)
    logger.info("Dask: local cluster of %d single-threaded workers", n)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def connect(address: str) -> Any:
    """A client of the scheduler at ``address``.

    Raises
    ------
    SchedulerUnreachable
        When it does not answer within :data:`CONNECT_TIMEOUT` (the message says what to do).
    """
    from distributed import Client

    try:
        return Client(address, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError) as exc:
        raise SchedulerUnreachable(
            f"cannot reach the Dask scheduler at {address} ({exc}); start one (dask scheduler) or leave "
            f"--scheduler and ${SCHEDULER_ENV} unset for a local cluster"
        ) from None


def run_single_threaded(fn: Callable[..., T], *args: Any) -> T:
    """Run ``fn(*args)`` with numba and BLAS limited to one thread in this thread (module docstring)."""
    import numba

    from engine.parallel import single_threaded_blas

    numba.set_num_threads(1)
    with single_threaded_blas():
        return fn(*args)


class Progress:
    """Progress of ``total`` items: a bar on a terminal (stderr), a log line per item otherwise."""

    def __init__(self, total: int, label: str, done: int = 0) -> None:
        self.total, self.label, self.done = total, label, done
        self.t0 = time.perf_counter()
        self.tty = sys.stderr.isatty()

    def step(self, what: str) -> None:
        """One more item finished (``what`` says which and how)."""
        self.done += 1
        elapsed = time.perf_counter() - self.t0
        if self.tty:
            width = 30
            filled = round(width * self.done / max(self.total, 1))
            sys.stderr.write(
                f"\r{self.label} [{'#' * filled}{'.' * (width - filled)}] {self.done}/{self.total} {elapsed:.0f} s"
            )
            if self.done >= self.total:
                sys.stderr.write("\n")
            sys.stderr.flush()
        logger.info("%s %d/%d %s (%.0f s elapsed)", self.label, self.done, self.total, what, elapsed)


def map_cases(
    client: Any,
    fn: Callable[..., T],
    inputs: Mapping[str, tuple[Any, ...]],
    label: str = "case",
    done: int = 0,
    total: int | None = None,
) -> Iterator[tuple[str, T]]:
    """Run ``fn(*inputs[key])`` for every key on the cluster; yield ``(key, result)`` as each finishes.

    Each task runs through :func:`run_single_threaded`. Tasks are keyed by ``label`` and the key, so
    a task resubmitted after a worker's loss is the same task. A task that raises re-raises here.
    With ``client`` None (``dask_client(workers=0)``) the tasks run here, one after the other.
    """
    progress = Progress(total if total is not None else len(inputs) + done, label, done)
    if client is None:
        for key, args in inputs.items():
            result = fn(*args)
            progress.step(key)
            yield key, result
        return
    from distributed import as_completed

    futures = {
        client.submit(run_single_threaded, fn, *args, key=f"{label}-{key}", pure=False): key
        for key, args in inputs.items()
    }
    for fut in as_completed(futures):
        key = futures[fut]
        result = fut.result()
        progress.step(key)
        yield key, result
