"""Protocol 1, one diagnosis at a time: the times of a finished run's cases of one expected answer.

A protocol-1 run's own times are throughput figures (``--workers 2``: two diagnoses at once, one
core each). Issue 4's budget is one diagnosis under 30 s on 2 cores. This takes the first
``--n`` cases (in id order: no choice by outcome) whose expected answer is ``--expected``
(``explained``, ``unexplained`` or ``no_gap``, from the run's ``report.json``), diagnoses them one
after the other in this process with every core, and prints one JSON line per case (its time, the
answer, and the run's own time of it) and a summary line: median and 90th percentile with the
order-statistic 95 % intervals of :func:`engine.validation.stats.quantile_interval`, and the share
over ``--budget`` seconds. The ratio against the run's own times of the same cases is printed as the
baseline (another process and machine load: a reading, not a benchmark of code against code).

Example (left-out records of the seed-227 run, about 15 min on 2 idle cores)::

    python lab/scripts/v1_case_times.py out/validation-v1-seed227 --expected unexplained --n 12

``--run-times`` diagnoses nothing: it prints the run's own times (two at once) by expected answer,
the number of cases, the median, the maximum and how many exceed ``--budget``.

The run's cases are development data once it is scored; the times do not depend on the answers,
but they do on what else the machine runs (the load average is printed).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import time
from pathlib import Path

import numpy as np

from engine.diagnosis.diagnose import DiagnosisSettings
from engine.diagnosis.validation import BlindCase, _diagnose_case
from engine.validation.stats import quantile_interval


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="a finished protocol-1 run (cases/, report.json)")
    ap.add_argument("--expected", default="unexplained", choices=("explained", "unexplained", "no_gap"))
    ap.add_argument("--n", type=int, default=12, help="cases, the first in id order")
    ap.add_argument("--budget", type=float, default=30.0, help="seconds (issue 4: 30)")
    ap.add_argument(
        "--run-times", action="store_true", help="only summarise the run's own (throughput) times by expected answer"
    )
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, stream=sys.stderr)
    report = args.run / "report.json"
    if not report.is_file():
        ap.error(f"{report} is missing: score the run first (backlash validate --protocol 1 ...)")
    doc = json.loads(report.read_text())
    if doc.get("protocol", 1) != 1 or not all("expected" in r for r in doc.get("per_case") or [{}]):
        ap.error(
            f"{report} is not a protocol-1 report (per-case rows with the expected answer); for protocol 2 use lab/scripts/rediagnose.py"
        )
    rows = sorted(doc["per_case"], key=lambda r: r["case_id"])
    if args.run_times:
        for expected in ("no_gap", "explained", "unexplained"):
            secs = np.asarray([r["seconds"] for r in rows if r["expected"] == expected], dtype=float)
            if secs.size:
                line = {"expected": expected, "n": int(secs.size), "median": round(float(np.median(secs)), 1)}
                line |= {"max": round(float(secs.max()), 1), f"over_{args.budget:g}_s": int(np.sum(secs > args.budget))}
                print(json.dumps(line), flush=True)
        return 0
    chosen = [r for r in rows if r["expected"] == args.expected][: args.n]
    if not chosen:
        ap.error(f"the run holds no case whose expected answer is {args.expected}")
    settings = DiagnosisSettings()
    times, theirs = [], []
    for row in chosen:
        case = BlindCase.from_dict(json.loads((args.run / "cases" / f"{row['case_id']}.json").read_text()))
        t0 = time.perf_counter()
        out = _diagnose_case(case, settings)
        seconds = time.perf_counter() - t0
        times.append(seconds)
        theirs.append(float(row["seconds"]))
        verdict = out["verdict"]
        line = {"case_id": row["case_id"], "seconds": round(seconds, 2), "run_seconds": round(row["seconds"], 2)}
        line |= {"status": verdict["status"], "effect": verdict.get("effect"), "run_status": row["status"]}
        print(json.dumps(line), flush=True)
    summary: dict[str, object] = {"expected": args.expected, "n": len(times), "load_average": os.getloadavg()}
    for name, q in (("median", 0.5), ("p90", 0.9)):
        est = quantile_interval(times, q)
        summary[name] = [None if v is None else round(v, 1) for v in (est.value, est.low, est.high)]
    summary[f"over_{args.budget:g}_s"] = int(np.sum(np.asarray(times) > args.budget))
    summary["ratio_to_run_medians"] = round(float(np.median(times) / np.median(theirs)), 2)
    print(json.dumps(summary), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
