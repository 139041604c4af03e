"""Speed benchmark of the numba kernel against scipy's solve_ivp in the same process.

Both simulate the paper's full grid (4 c x 6 widths x 7 J1 = 168 cases). The
baseline is :func:`engine.simulation.reference.reference_simulate` with LSODA,
rtol 1e-8, a numpy right-hand side and the event located by solve_ivp's
events. Agreement is checked against MODEL.md section 4 (0.5 % of each
channel's peak-to-peak, t_e within 1 us).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from engine.simulation.parameters import Case, full_grid
from engine.simulation.reference import reference_inputs, reference_simulate
from engine.simulation.simulator import SimulationResult, simulate_batch

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class BenchmarkResult:
    n_cases: int
    kernel_seconds: float
    baseline_seconds: float
    max_rel_error: float
    max_event_time_error: float

    @property
    def kernel_rate(self) -> float:
        """Records per second of the numba kernel."""
        return self.n_cases / self.kernel_seconds

    @property
    def baseline_rate(self) -> float:
        """Records per second of solve_ivp (LSODA, rtol 1e-8)."""
        return self.n_cases / self.baseline_seconds

    @property
    def speedup(self) -> float:
        return self.kernel_rate / self.baseline_rate

    def lines(self) -> list[str]:
        return [
            f"cases: {self.n_cases} (full paper grid)",
            f"numba kernel:          {self.kernel_rate:9.1f} records/s ({self.kernel_seconds:.3f} s, best of its runs between the baseline's chunks, compiled)",
            f"solve_ivp LSODA 1e-8:  {self.baseline_rate:9.1f} records/s ({self.baseline_seconds:.3f} s)",
            f"agreement: max error {100 * self.max_rel_error:.4f} % of peak-to-peak (limit 0.5 %), "
            f"max |t_e difference| {self.max_event_time_error:.2e} s (limit 1e-6 s)",
            f"speedup: {self.speedup:.1f}x",
        ]


#: Cases of the baseline between two timings of the kernel (:func:`run_benchmark`).
BASELINE_CHUNK = 24


def run_benchmark(
    cases: list[Case] | None = None, progress: Callable[[int, int], None] | None = None
) -> BenchmarkResult:
    """Time the kernel and the solve_ivp baseline on ``cases`` (default: the full grid).

    The two share the machine's state: the baseline runs in chunks of :data:`BASELINE_CHUNK` cases,
    and the kernel simulates every case once before the first chunk and after each (its time is
    the best of these runs). A machine whose speed drifts during the run's 10-20 s then slows
    both alike, where one kernel timing before the whole baseline would not.
    """
    cases = full_grid() if cases is None else cases
    simulate_batch(cases[:2])  # compile / load the cache outside the timing

    def kernel_run() -> tuple[float, SimulationResult]:
        t0 = time.perf_counter()
        result = simulate_batch(cases)
        return time.perf_counter() - t0, result

    best, fast = kernel_run()
    baseline = 0.0
    errs, dts = [], []
    for start in range(0, len(cases), BASELINE_CHUNK):
        t0 = time.perf_counter()
        refs = [
            reference_simulate(*reference_inputs(case), method="LSODA", rtol=1e-8, atol=1e-10)
            for case in cases[start : start + BASELINE_CHUNK]
        ]
        baseline += time.perf_counter() - t0
        for i, ref in enumerate(refs, start):
            pp = np.ptp(ref.channels, axis=1)
            errs.append(np.max(np.abs(fast.channels[i] - ref.channels), axis=1) / np.where(pp > 0, pp, 1.0))
            dts.append(abs(fast.event_times[i] - ref.event_time))
        if progress:
            progress(start + len(refs), len(cases))
        best = min(best, kernel_run()[0])
    return BenchmarkResult(len(cases), best, baseline, float(np.max(errs)), float(np.max(dts)))
