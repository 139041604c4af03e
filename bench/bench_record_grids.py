"""Benchmark: what a record's grid costs the gap diagnosis and the simulator.

``python bench/bench_record_grids.py [--repeat N] [--intervals 1e-5,2.5e-5,...]``

One plant case (K = 7.5 mm, J1 = 0.85 kg m^2, c = 1.0; c1 known) is rendered on the
minimum grid of each interval (4.8 ms before to 200 ms after the event) with 40 dB
noise, clean and with ``load_inertia`` = 1.3, and diagnosed on 2 cores. Every figure is a
ratio against the 0.1 ms record, measured in the same process (best of ``--repeat``).
The simulator line is the time of one batch of 16 cases on the grid.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from collections.abc import Callable
from functools import partial
from typing import TypeVar

import numpy as np

from engine.diagnosis import DiagnosisResult, diagnose
from engine.records import Record, SampleGrid, record_from_data
from engine.simulation import PlantParameters, add_white_noise, simulate, simulate_batch

CASE = PlantParameters(K=0.0075, J1=0.85, c=1.0)
T = TypeVar("T")
DEFAULT_INTERVALS = (1e-4, 1e-5, 2.5e-5, 5e-5, 2e-4, 5e-4, 1e-3)


def _record(ts: float, effects: dict[str, float] | None) -> Record:
    sim = simulate(CASE, effects, grid=SampleGrid.protocol(ts))
    rng = np.random.default_rng(0)
    noisy = {c: add_white_noise(x, 40.0, rng) for c, x in sim.channels.items()}
    return record_from_data(noisy, ts, sim.event_index, {"c1": 0.2})


def _best(fn: Callable[[], T], repeat: int) -> tuple[float, T]:
    """Best wall time [s] of ``repeat`` calls, and the last result."""
    best = float("inf")
    for _ in range(max(repeat, 1)):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def _diagnosis(rec: Record, repeat: int) -> tuple[float, DiagnosisResult]:
    return _best(lambda: diagnose(rec), repeat)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=1)
    p.add_argument("--intervals", default=",".join(f"{x:g}" for x in DEFAULT_INTERVALS))
    args = p.parse_args(sys.argv[1:] if argv is None else argv)
    logging.basicConfig(level=logging.WARNING)
    intervals = [float(x) for x in args.intervals.split(",")]
    if 1e-4 not in intervals:
        intervals.insert(0, 1e-4)
    cases = [CASE] * 16
    simulate_batch(cases[:2], grid=SampleGrid.protocol(1e-4))  # compile
    rows = []
    for ts in intervals:
        grid = SampleGrid.protocol(ts)
        t_sim, _ = _best(partial(simulate_batch, cases, grid=grid), max(args.repeat, 3))
        clean, effect = _record(ts, None), _record(ts, {"load_inertia": 1.3})
        t_clean, r_clean = _diagnosis(clean, args.repeat)
        t_eff, r_eff = _diagnosis(effect, args.repeat)
        rows.append((ts, grid.n_samples, t_sim, t_clean, r_clean.verdict.status, t_eff, r_eff.verdict.effect))
    base = next(r for r in rows if r[0] == 1e-4)
    out = [
        "| interval | samples | simulate 16 cases [s] (ratio) | diagnose clean [s] (ratio) | verdict | "
        "diagnose load_inertia [s] (ratio) | named |",
        "|---|---|---|---|---|---|---|",
    ]
    for ts, n, ts_sim, tc, vc, te, ve in rows:
        out.append(
            f"| {ts * 1e6:g} us | {n} | {ts_sim:.3f} ({ts_sim / base[2]:.2f}x) | {tc:.1f} ({tc / base[3]:.2f}x) | {vc} | "
            f"{te:.1f} ({te / base[5]:.2f}x) | {ve} |"
        )
    sys.stdout.write("\n".join(out) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
