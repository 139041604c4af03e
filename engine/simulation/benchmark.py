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
from engine.simulation.simulator import simulate_batch

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
            f"numba kernel:          {self.kernel_rate:9.1f} records/s ({self.kernel_seconds:.3f} s, best of 3, compiled)",
            f"solve_ivp LSODA 1e-8:  {self.baseline_rate:9.1f} records/s ({self.baseline_seconds:.3f} s)",
            f"agreement: max error {100 * self.max_rel_error:.4f} % of peak-to-peak (limit 0.5 %), "
            f"max |t_e difference| {self.max_event_time_error:.2e} s (limit 1e-6 s)",
            f"speedup: {self.speedup:.1f}x",
        ]


def run_benchmark(
    cases: list[Case] | None = None, progress: Callable[[int, int], None] | None = None
) -> BenchmarkResult:
    """Time the kernel and the solve_ivp baseline on ``cases`` (default: the full grid)."""
    cases = full_grid() if cases is None else cases
    simulate_batch(cases[:2])  # compile / load the cache outside the timing
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        fast = simulate_batch(cases)
        best = min(best, time.perf_counter() - t0)
    t0 = time.perf_counter()
    errs, dts = [], []
    for i, case in enumerate(cases):
        ref = reference_simulate(*reference_inputs(case), method="LSODA", rtol=1e-8, atol=1e-10)
        pp = np.ptp(ref.channels, axis=1)
        errs.append(np.max(np.abs(fast.channels[i] - ref.channels), axis=1) / np.where(pp > 0, pp, 1.0))
        dts.append(abs(fast.event_times[i] - ref.event_time))
        if progress:
            progress(i + 1, len(cases))
    baseline = time.perf_counter() - t0
    return BenchmarkResult(len(cases), best, baseline, float(np.max(errs)), float(np.max(dts)))
