"""Benchmark: calibrations whose early-window fits render only the samples they fit, against whole records.

The calibration's global search scores its Sobol points on the record's first 20 ms after the
event, and its continuation fits 20, 50 and 100 ms before the whole record
(:mod:`engine.diagnosis.calibration`). Since 2026-11-27 the objective renders only the samples a
horizon holds (:meth:`engine.diagnosis.objective.Objective.simulate`; the kernel stops after
the last of them, :func:`engine.simulation.run_cases` with ``first``). The baseline, run in the
same process on the same records, is the objective as it was: every simulation renders the whole
record and the horizon is cut from it afterwards.

The records are drawn here: plants uniform in the plausible box of issue 10 (K 1-15 mm, J1
0.6-1.2 kg m^2, c 0.5-2.0), MODEL.md's grid, white noise at 40 dB, no effect. Each record is
calibrated once per variant (JIT warm-up first), the variants alternating; the fitted values must
be the same bit for bit (the samples are), else the benchmark stops with an error.

Example::

    python bench/bench_horizon.py --records 8 --seed 3

Prints one JSON object: per record the seconds of both variants and their ratio, and the median
ratio (baseline / horizon) with its range.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from typing import Any

import numpy as np

logger = logging.getLogger("bench_horizon")


def _records(n: int, seed: int) -> list[Any]:
    """``n`` noisy records of plants drawn uniformly in the plausible box."""
    from _plants import uniform_plants

    from engine.constants import CHANNELS, PLAUSIBLE_RANGE
    from engine.records import Record
    from engine.simulation import Case, simulate_batch
    from engine.simulation.noise import add_white_noise

    rng = np.random.default_rng(seed)
    plants = uniform_plants(PLAUSIBLE_RANGE, n, rng)
    sims = simulate_batch([Case(p) for p in plants])
    g = sims.grid
    return [
        Record(
            dict(zip(CHANNELS, add_white_noise(sims.channels[i], 40.0, rng, axis=1), strict=True)),
            g.sample_interval,
            g.event_index,
            conditions={"c1": 0.2},  # the calibration fits K, J1 and c
        )
        for i in range(n)
    ]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--records", type=int, default=8, help="records calibrated (default 8)")
    ap.add_argument("--seed", type=int, default=3, help="seed of the plants and the noise")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s", stream=sys.stderr)

    from unittest import mock

    from engine.diagnosis import calibration
    from engine.diagnosis.objective import Objective

    class WholeRecord(Objective):
        """The baseline: every simulation renders the whole record; the horizon is cut afterwards."""

        def simulate(self, U: np.ndarray, solver: Any, horizon: int | None = None) -> tuple[np.ndarray, np.ndarray]:
            sims, ok = super().simulate(U, solver, None)
            return sims[:, :, : self.grid.n_samples if horizon is None else horizon], ok

    records = _records(args.records, args.seed)
    calibration.calibrate(records[0])  # JIT warm-up
    rows = []
    for i, rec in enumerate(records):
        t0 = time.perf_counter()
        with mock.patch.object(calibration, "Objective", WholeRecord):
            base = calibration.calibrate(rec)
        t1 = time.perf_counter()
        new = calibration.calibrate(rec)
        t2 = time.perf_counter()
        if base.values != new.values or base.chi2 != new.chi2:
            raise SystemExit(f"record {i}: the two variants fitted different values ({base.values} vs {new.values})")
        rows.append({"record": i, "baseline_s": t1 - t0, "horizon_s": t2 - t1, "ratio": (t1 - t0) / (t2 - t1)})
        logger.info(
            "record %d: whole records %.2f s, horizons %.2f s, ratio %.2f", i, t1 - t0, t2 - t1, rows[-1]["ratio"]
        )
    ratios = np.array([r["ratio"] for r in rows])
    sys.stdout.write(
        json.dumps(
            {
                "records": len(rows),
                "seed": args.seed,
                "median_ratio": float(np.median(ratios)),
                "min_ratio": float(ratios.min()),
                "max_ratio": float(ratios.max()),
                "rows": rows,
            },
            indent=1,
        )
        + "\n"
    )
    sys.stdout.write(f"speedup: {np.median(ratios):.2f}x (median over {len(rows)} calibrations)\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
