"""Benchmark: numba kernel vs scipy solve_ivp (LSODA, rtol 1e-8) on the 168-case grid.

Run as ``backlash bench`` or ``python bench/bench_simulator.py``; the last line
is ``speedup: <ratio>x``. Per core, as issue 54 measures it::

    NUMBA_NUM_THREADS=1 python bench/bench_simulator.py --json docs/validation/kernel-speed/report.json

``--json FILE`` also writes the figures, the numba thread count and the commit, which
``docs/gen.py`` renders into docs/identification.md (region ``kernel-speed``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
from pathlib import Path

from engine.simulation.benchmark import BASELINE_CHUNK, run_benchmark
from engine.validation.provenance import code_version


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args(argv)

    def progress(i: int, n: int) -> None:
        if i % 24 == 0 or i == n:
            sys.stderr.write(f"\rbaseline (solve_ivp): {i}/{n} cases")
            sys.stderr.flush()
            if i == n:
                sys.stderr.write("\n")

    result = run_benchmark(progress=progress)
    sys.stdout.write("\n".join(result.lines()) + "\n")
    if args.json:
        import numba

        report = {
            "n_cases": result.n_cases,
            "kernel_seconds": result.kernel_seconds,
            "kernel_runs": 1 + -(-result.n_cases // BASELINE_CHUNK),
            "baseline_seconds": result.baseline_seconds,
            "kernel_records_per_s": result.kernel_rate,
            "baseline_records_per_s": result.baseline_rate,
            "speedup": result.speedup,
            "max_rel_error": result.max_rel_error,
            "max_event_time_error_s": result.max_event_time_error,
            "numba_threads": numba.get_num_threads(),
            "numba_num_threads_env": os.environ.get("NUMBA_NUM_THREADS"),
            "cpus": os.cpu_count(),
            "processor": platform.processor() or platform.machine(),
            "commit": code_version()["describe"] or "unknown",
            "command": "NUMBA_NUM_THREADS=1 python bench/bench_simulator.py --json " + args.json.as_posix(),
        }
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(report, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
