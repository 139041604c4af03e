"""Benchmark: numba kernel vs scipy solve_ivp (LSODA, rtol 1e-8) on the 168-case grid.

Run as ``backlash bench`` or ``python bench/bench_simulator.py``; the last line
is ``speedup: <ratio>x``.
"""

from __future__ import annotations

import sys

from engine.simulation.benchmark import run_benchmark


def main() -> int:
    def progress(i: int, n: int) -> None:
        if i % 24 == 0 or i == n:
            sys.stderr.write(f"\rbaseline (solve_ivp): {i}/{n} cases")
            sys.stderr.flush()
            if i == n:
                sys.stderr.write("\n")

    result = run_benchmark(progress=progress)
    sys.stdout.write("\n".join(result.lines()) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
