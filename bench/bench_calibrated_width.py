"""Benchmark: the calibrated K as a continuous width identifier, on the main job's held-out records.

``python bench/bench_calibrated_width.py [n_cases]`` (default 20 cases per channel and noise level).
"""

from __future__ import annotations

import logging
import sys

from engine.evaluation.continuous import continuous_markdown, evaluate_continuous


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    n = int(argv[0]) if argv else 20
    sys.stdout.write(continuous_markdown(evaluate_continuous(n_cases=n)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
